"""
Node parameters declared with descriptors: the contract's spec type and descriptor builder.

The one definition is hexacal_msgs_py.node_parameters (the simulated driver uses it too); the
nodes import it from here.

Kept apart from nodes/runtime.py, which entry points import before anything else (its imports must
stay minimal so a Ctrl-C during start-up finds the signal handlers in place).
"""

from __future__ import annotations

from hexacal_msgs_py.node_parameters import parameter_descriptor, ParameterSpec

__all__ = ['ParameterSpec', 'parameter_descriptor']

"""
Studies built on the core.

The paper's section 4 (accuracy), the device-defect study, planning studies.
"""

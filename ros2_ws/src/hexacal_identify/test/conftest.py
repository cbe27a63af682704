"""
Unit-test configuration: calibration stores under a temporary directory, never the user's.

Set at import, before any test runs: a session or node without an explicit store uses
default_store_dir(model), which $HEXACAL_STORE moves here.
"""

from __future__ import annotations

import os
import tempfile

os.environ['HEXACAL_STORE'] = tempfile.mkdtemp(prefix='hexacal-test-store-')

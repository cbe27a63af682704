"""`python -m hexacal_identify.cli`: the hexacal command."""

import sys

from .commands import main

sys.exit(main())

"""`python -m hexacal_identify.cli`: the hexacal command."""
import sys

from hexacal_identify.cli.commands import main

sys.exit(main())

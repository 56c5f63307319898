"""`python -m dynval` = the `dynval` command."""
import sys

from dynval.cli import main

sys.exit(main())

"""`python -m anytime` is the `anytime` command."""

import sys

from anytime.cli import main

sys.exit(main())

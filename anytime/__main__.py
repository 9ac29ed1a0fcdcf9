"""`python -m anytime` is the `anytime` command."""

import sys

from anytime.launch import main

sys.exit(main())

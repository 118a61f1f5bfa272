"""``python -m closure_nlp.cli``: the command line."""

import sys

from closure_nlp.cli.main import main

sys.exit(main())

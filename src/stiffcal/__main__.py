"""``python -m stiffcal ...``: the command line (:func:`stiffcal.cli.main`), as the installed ``stiffcal``."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())

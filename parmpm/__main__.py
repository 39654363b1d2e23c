"""``python -m parmpm``: the command line (:mod:`parmpm.cli.main`)."""
import sys

from parmpm.cli.main import main

if __name__ == "__main__":
    sys.exit(main())

"""``python -m nsm_continuation``: the command line (:mod:`nsm_continuation.cli`)."""

import sys

from nsm_continuation.cli import main

if __name__ == "__main__":
    sys.exit(main())

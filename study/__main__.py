"""``python -m study``: the same as the ``study`` command (:mod:`study.launch`)."""

import sys

from study.launch import main

if __name__ == "__main__":
    sys.exit(main())

"""``python -m study``: the same as the ``study`` command."""

import sys


def _main() -> int:
    try:  # a Ctrl-C while the command is still being imported: one line too
        from study.cli import main

        return main()
    except KeyboardInterrupt:
        print("study: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(_main())

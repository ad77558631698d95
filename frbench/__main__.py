"""``python -m frbench`` (and ``torchrun ... -m frbench train ...``): the ``frbench`` command."""

import sys

from frbench.cli import main

if __name__ == "__main__":
    sys.exit(main())

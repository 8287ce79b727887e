"""``python -m rrls`` is the ``rrls`` command."""

import sys

from rrls.cli import main

sys.exit(main())

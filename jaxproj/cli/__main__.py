"""``python -m jaxproj.cli``: the ``jaxproj`` command."""

import sys

from jaxproj.cli.main import main

sys.exit(main())

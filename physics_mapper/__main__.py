"""``python -m physics_mapper``: the same as the ``physics-mapper`` console script."""

import sys

from physics_mapper.cli import main

sys.exit(main())

"""``tumble.models``: the built-in systems, the module :mod:`tumble.physics.models` under its short public path.

One module under two names: importing this one puts :mod:`tumble.physics.models` in its place.
"""

import sys

from .physics import models

sys.modules[__name__] = models

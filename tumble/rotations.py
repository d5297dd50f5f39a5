"""``tumble.rotations``: rotations and quaternions, the module :mod:`tumble.physics.rotations` under its short public path.

One module under two names: importing this one puts :mod:`tumble.physics.rotations` in its place.
"""

import sys

from .physics import rotations

sys.modules[__name__] = rotations

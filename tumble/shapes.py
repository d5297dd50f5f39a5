"""``tumble.shapes``: bodies from shapes, the module :mod:`tumble.physics.shapes` under its short public path.

One module under two names: importing this one puts :mod:`tumble.physics.shapes` in its place.
"""

import sys

from .physics import shapes

sys.modules[__name__] = shapes

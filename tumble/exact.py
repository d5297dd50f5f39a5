"""``tumble.exact``: the torque-free closed form, the module :mod:`tumble.physics.exact` under its short public path.

One module under two names: importing this one puts :mod:`tumble.physics.exact` in its place.
"""

import sys

from .physics import exact

sys.modules[__name__] = exact

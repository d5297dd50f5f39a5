"""``tumble.theory``: linear theory, the module :mod:`tumble.physics.theory` under its short public path.

One module under two names: importing this one puts :mod:`tumble.physics.theory` in its place.
"""

import sys

from .physics import theory

sys.modules[__name__] = theory

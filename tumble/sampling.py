"""``tumble.sampling``: ensembles of initial spins, the module :mod:`tumble.engine.sampling` under its short public path.

One module under two names: importing this one puts :mod:`tumble.engine.sampling` in its place.
"""

import sys

from .engine import sampling

sys.modules[__name__] = sampling

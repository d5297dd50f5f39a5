"""``tumble.io``: result files, the module :mod:`tumble.output.io` under its short public path.

One module under two names: importing this one puts :mod:`tumble.output.io` in its place.
"""

import sys

from .output import io

sys.modules[__name__] = io

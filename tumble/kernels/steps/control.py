"""Hairer's step-size control of an error-controlled step, and the block of lanes whose tries it keeps.

``dop853.f``'s control (Hairer, Norsett & Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., sect. II.4,
its PI form of IV.2, "Lund stabilisation"): a try of ``h`` with error norm ``err`` is kept when ``err <= 1``; the next
step is ``h / fac``, ``fac = err^(1/8) / facold^beta / safety`` kept within ``[1 / largest, 1 / smallest]``
(``facold``: the last kept try's error, at least 1e-4; 1e-4 before the first), and after a rejection
``h / min(1 / smallest, err^(1/8) / safety)``, never grown on the next kept try. ``beta = 1/16``: the step follows the
error's trend, not its last value alone, and is rejected less (:data:`tumble.kernels.tableaux.DOP853`, where the
numbers are the method's data, says by how much). A non-finite error (a stage overflowed) gives the largest fall.

One sample's loop (:mod:`tumble.kernels.loops.adaptive_loop`) and a block's generated attempt, every lane at once
(:func:`tumble.kernels.steps.model_codegen.attempt_source`), call the same :func:`next_step`: branch-free, so that
the lanes' loop vectorises, and the same bits in both.

**The block.** The loop of :mod:`tumble.kernels.loops.adaptive_blocks` keeps a block's numbers in one flat array of
:data:`BLOCK` columns: the lanes' rows (each lane's time ``T``, step ``H``, ... at those offsets), then the states
``ys``, their rates ``ks``, and the state and rate each lane's try started from, ``y0s`` and ``k0s``, ``n`` rows each,
from :data:`STATES`: element ``(row, lane)`` at ``row * BLOCK + lane``. Every offset is a constant where the attempt
and the loop's passes index it, so LLVM sees that no two rows overlap and vectorises those loops without a check at
run time (passed as a dozen arrays, the attempt did not vectorise at all: the checks between them exceed LLVM's
limit).
"""

import math

from ..jit import jit
from ..tableaux import DOP853
from ..trig import _max, _min

__all__ = ["BLOCK", "FIRST_FACOLD", "LARGEST", "ROUND", "SAFETY", "SMALLEST", "STATES", "next_step", "root8",
           "state_row"]

SAFETY, SMALLEST, LARGEST = DOP853.safety, DOP853.smallest, DOP853.largest
#: The rounding unit of a step's time: a step below ``|t| ROUND 10`` cannot advance ``t``.
ROUND = 2.3e-16
assert DOP853.error_order + 1 == 8 and DOP853.beta == 1 / 16, "the control's roots are taken as square roots"
#: ``facold^beta`` before a sample's first kept try (``facold = 1e-4``, as ``dop853.f``).
FIRST_FACOLD = math.sqrt(math.sqrt(math.sqrt(math.sqrt(1e-4))))
#: ``1e-4^(1/8)``: the smallest ``facold`` (1e-4) as :func:`root8` gives it.
_SMALLEST_ROOT = math.sqrt(math.sqrt(math.sqrt(1e-4)))

#: Lanes of a block: a share of the samples steps in one block whose lanes take the next sample as theirs is done.
BLOCK = 32

#: The lanes' rows, by offset in the block: each lane's time, step, trial step (0: done), whether it steps, whether its
#: last try was rejected, whether this one was kept, the time it reaches, its next output time, its surface's value,
#: the time its try started from, its tries and kept steps, its control's ``facold^beta`` (:func:`next_step`), and its
#: try's squared error norms, of the 5th- and the 3rd-order estimates (left by an attempt's stages for its control).
(T, H, TRIAL_H, ACTIVE, LAST_REJECTED, KEPT, T_NEW, NEXT_OUT, G0, T_PREV, TRIES, ACCEPTED, FACOLD, ERR5, ERR3) = (
    BLOCK * row for row in range(15))
#: Where the states begin: ``ys``, ``ks``, ``y0s``, ``k0s`` (``n`` rows each).
STATES = 15 * BLOCK


def state_row(which, j, n):
    """The offset of component ``j`` of ``which`` (0: ``ys``, 1: ``ks``, 2: ``y0s``, 3: ``k0s``) for ``n``
    components."""
    return STATES + (which * n + j) * BLOCK


@jit(inline=True)
def root8(x):
    """``x ** (1/8)``, the control's root, as three square roots: a few cycles, and vectorised, where ``pow`` takes
    tens."""
    return math.sqrt(math.sqrt(math.sqrt(x)))


@jit(inline=True)
def next_step(err, h, last_rejected, facold):
    """``(the step to try next, facold^beta after it)`` after a try of ``h`` with error norm ``err``, ``facold`` the
    control's ``facold^beta`` before it: grown by at most ``largest`` when the try is kept (``err <= 1``; not grown when
    the try before it was rejected, ``last_rejected`` not 0), shrunk by its factor when not (by ``1 / smallest`` for a
    non-finite error), ``facold`` then unchanged. Both steps are made and one chosen (branch-free, so that a block's
    lanes vectorise): an error of 0 (a steady spin's) makes the shrunk one infinite, never chosen."""
    root = root8(err) if err < 1e300 else 1e300  # err^(1/8); NaN and inf as a huge error
    inverse = 1.0 / (root * (1.0 / SAFETY))  # the one division a lane (a block's loop runs at its divisions' rate)
    grow = h * _min(LARGEST, _max(SMALLEST, facold * inverse))
    grow = _min(grow, h) if last_rejected != 0.0 else grow
    shrink = h * _max(SMALLEST, inverse)
    kept = err <= 1.0
    return (grow if kept else shrink), (math.sqrt(_max(root, _SMALLEST_ROOT)) if kept else facold)

"""The screen of the models' drift observer: a branch-free test per sample that vectorises across a block.

Each step, while invariants' drifts are tracked, the time loop (:func:`tumble.kernels.loops.block_loop.run_block`) first asks
its system's screen (the generated :func:`tumble.kernels.steps.model_steps.drift_suspects`, the free body's
:func:`tumble.kernels.loops.free_body_parts.drift_suspects`) whether any sample of a block comes near the drift limit or is
non-finite; only then do the exact per-sample observers run (run every step, those scalar loops had cost as
much as a gravity gradient's rk4 step, the screen costs a fifth of it).
"""

import math

from ..jit import jit

__all__ = ["SCREEN_ATOL", "SCREEN_RTOL", "suspect"]

#: The screen flags drifts beyond ``limit (1 − SCREEN_RTOL) − SCREEN_ATOL``, so that its rounding (vectorised, perhaps
#: fused differently from the exact observer's: a drift is a difference of invariants of the size of their scale, so
#: a few eps of it) can never miss a sample the exact check stops.
SCREEN_RTOL = 1e-6
SCREEN_ATOL = 1e-13


@jit(inline=True)
def suspect(i, active, x0, inverse_scale, screen, x1, x2, x3, total):
    """1 if sample ``i`` of a block is active and drifting beyond ``screen`` (its invariants ``x`` against their
    initial ``x0``, times the inverses of their scales) or has a non-finite component (``total``, the sum of its
    components, is then not finite; a finite sum that overflows is a false alarm, checked exactly), else 0; no branch,
    no inner loop, so that the loop over samples vectorises."""
    calm = ((abs(x1 - x0[0, i]) * inverse_scale[0, i] <= screen) & (abs(x2 - x0[1, i]) * inverse_scale[1, i] <= screen)
            & (abs(x3 - x0[2, i]) * inverse_scale[2, i] <= screen) & math.isfinite(total)) | (not active[i])
    return 0 if calm else 1  # (written so: a branch on active[i] stops LLVM vectorising the loop)

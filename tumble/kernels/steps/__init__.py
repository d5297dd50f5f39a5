"""The steps: one step of every method for every system, a sample or a block of samples at a time.

The free body's hand-written pieces (:mod:`.steppers`: Euler's equations, the torque, the exact sub-flows) and its
generated steps (:mod:`.fused`, by :mod:`.codegen` from :mod:`tumble.kernels.tableaux`); the built-in systems'
generated steps and dispatch (:mod:`.model_steps`, by :mod:`.model_codegen` from the equations of
:mod:`tumble.kernels.systems`) and their Lie–Poisson splittings (:mod:`.model_splittings`); a user's System's steps,
generated when it first runs (:mod:`.system_steps`); the attitude's steps (:mod:`.attitude`) and the drift screen
(:mod:`.drift_screen`). Nothing here loops over time: :mod:`tumble.kernels.loops` does.
"""

__all__ = ["attitude", "codegen", "drift_screen", "fused", "model_codegen", "model_splittings", "model_steps",
           "steppers", "system_steps"]

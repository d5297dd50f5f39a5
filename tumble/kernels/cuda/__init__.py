"""The CUDA launchers: one thread per sample, float64, each imported on its first use through the door's
``device_*`` functions (:mod:`tumble.kernels`), never by ``import tumble`` (importing them imports ``numba.cuda``).

What they share (:mod:`.launch`), the free body (:mod:`.rigid_body`), its attitude (:mod:`.attitude_steps`), the
closed form (:mod:`.closed_form`), the phase fit (:mod:`.phase_fit`), the built-in systems (:mod:`.models`), a system
given by its rate (:mod:`.rate_loop`) and the tangent flow (:mod:`.tangent_flow`).
"""

__all__ = ["attitude_steps", "closed_form", "launch", "models", "phase_fit", "rate_loop", "rigid_body", "tangent_flow"]

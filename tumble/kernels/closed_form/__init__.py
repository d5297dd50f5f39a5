"""The closed form of the torque-free motion: Jacobi elliptic functions (:mod:`.elliptic`) and the attitude
(:mod:`.elliptic_attitude`), the kernels of :mod:`tumble.physics.exact`."""

__all__ = ["elliptic", "elliptic_attitude"]

"""Systems written by hand, as a user writes a ``tumble.System``, shared by the test modules that check a built-in
model against them. A System's rate is compiled once per process and System object (tumble/engine/system_runs.py), so
one object here, with its parameters given per call, is one compile for every test that uses it on a worker (the
tests that use it are in one xdist group, ``user_systems``: one worker runs them all)."""

import math

import tumble

#: The xdist group (pyproject's ``--dist loadgroup``) of the tests that compile the Systems of this module.
GROUP = "user_systems"


def heavy_top(t, y, p, dydt):
    """The heavy top, centre of mass anywhere: I w' = (I w) x w + mgl (g x c), g' = g x w; p = (I1, I2, I3, mgl,
    c1, c2, c3), c the unit direction of the centre of mass from the pivot in body axes."""
    gc1 = y[4] * p[6] - y[5] * p[5]
    gc2 = y[5] * p[4] - y[3] * p[6]
    gc3 = y[3] * p[5] - y[4] * p[4]
    dydt[0] = ((p[1] - p[2]) * y[1] * y[2] + p[3] * gc1) / p[0]
    dydt[1] = ((p[2] - p[0]) * y[2] * y[0] + p[3] * gc2) / p[1]
    dydt[2] = ((p[0] - p[1]) * y[0] * y[1] + p[3] * gc3) / p[2]
    dydt[3] = y[4] * y[2] - y[5] * y[1]
    dydt[4] = y[5] * y[0] - y[3] * y[2]
    dydt[5] = y[3] * y[1] - y[4] * y[0]


def heavy_top_jacobian(t, y, p, J):
    """The heavy top's Jacobian ∂f/∂y, every entry set."""
    J[0, 1], J[0, 2] = (p[1] - p[2]) * y[2] / p[0], (p[1] - p[2]) * y[1] / p[0]
    J[0, 4], J[0, 5] = p[3] * p[6] / p[0], -p[3] * p[5] / p[0]
    J[1, 0], J[1, 2] = (p[2] - p[0]) * y[2] / p[1], (p[2] - p[0]) * y[0] / p[1]
    J[1, 3], J[1, 5] = -p[3] * p[6] / p[1], p[3] * p[4] / p[1]
    J[2, 0], J[2, 1] = (p[0] - p[1]) * y[1] / p[2], (p[0] - p[1]) * y[0] / p[2]
    J[2, 3], J[2, 4] = p[3] * p[5] / p[2], -p[3] * p[4] / p[2]
    J[3, 1], J[3, 2], J[3, 4], J[3, 5] = -y[5], y[4], y[2], -y[1]
    J[4, 0], J[4, 2], J[4, 3], J[4, 5] = y[5], -y[3], -y[2], y[0]
    J[5, 0], J[5, 1], J[5, 3], J[5, 4] = -y[4], y[3], y[1], -y[0]
    J[0, 0] = J[0, 3] = J[1, 1] = J[1, 4] = J[2, 2] = J[3, 0] = J[3, 3] = J[4, 1] = J[4, 4] = J[5, 2] = J[5, 5] = 0.0
    J[2, 5] = 0.0


HEAVY_TOP_STATE = ("w1", "w2", "w3", "g1", "g2", "g3")
HEAVY_TOP_PARAMETERS = {"I1": 2.0, "I2": 2.5, "I3": 3.0, "mgl": 0.5, "c1": 0.0, "c2": 0.0, "c3": 1.0}
HEAVY_TOP = tumble.System(heavy_top, state=HEAVY_TOP_STATE, parameters=HEAVY_TOP_PARAMETERS, name="heavy top by hand")
#: The same with its Jacobian: exact tangents, as the built-in's.
HEAVY_TOP_WITH_JACOBIAN = tumble.System(heavy_top, state=HEAVY_TOP_STATE, parameters=HEAVY_TOP_PARAMETERS,
                                        jacobian=heavy_top_jacobian, name="heavy top by hand, with its Jacobian")


def rotor(t, y, p, dydt):
    """A driven, damped pendulum that turns over and over: its angle grows without bound."""
    dydt[0] = y[1]
    dydt[1] = -p[0] * math.sin(y[0]) - p[1] * y[1] + p[2] * math.cos(p[3] * t)


def rotor_jacobian(t, y, p, J):
    J[0, 0], J[0, 1] = 0.0, 1.0
    J[1, 0], J[1, 1] = -p[0] * math.cos(y[0]), -p[1]


#: The rotor's parameters: stiffness k, damping c, drive amplitude a and frequency w.
ROTOR = {"k": 1.0, "c": 0.1, "a": 1.2, "w": 0.9}

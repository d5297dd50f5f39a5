"""Integrator coefficients as data.

Two kinds of method share two generic steppers (:mod:`tumble.kernels.steps.steppers`):

* explicit Runge–Kutta methods, given by a Butcher tableau ``(A, b, c)``;
* Lie–Poisson splittings of the free rigid body, given by a sequence of exact sub-flows and the fraction of
  the step each one takes. The free-body Hamiltonian ``H = sum_a L_a**2 / (2 I_a)`` is split into its three
  terms; the flow of each is an exact rotation of ``L`` about one body axis (McLachlan 1993, "Explicit
  Lie-Poisson integration and the Euler equations", Phys. Rev. Lett. 71, 3043; Hairer, Lubich & Wanner,
  *Geometric Numerical Integration*, 2nd ed., sect. VII.5). A body torque enters as a fourth sub-flow
  ``w' = N(t, w) / I`` that also advances time.

Every table checks itself when it is built (rows of ``A`` sum to ``c``, ``b`` and each sub-flow's
fractions sum to 1), in the spirit of diffrax's ``ButcherTableau``.
"""

from typing import NamedTuple

import numpy as np

__all__ = [
    "ALL_METHODS", "ButcherTableau", "TABLEAUX", "IMPLICIT_MIDPOINT", "METHOD_ORDER", "RK4", "RK8", "SYMPLECTIC_EULER",
    "SPLITTING2", "SPLITTING4", "Splitting",
    "ROTATE_1", "ROTATE_2", "ROTATE_3", "TORQUE",
]

# Sub-flow codes used in splitting sequences.
ROTATE_1, ROTATE_2, ROTATE_3, TORQUE = 0, 1, 2, 3


class ButcherTableau(NamedTuple):
    """An explicit Runge–Kutta method: stages ``k_s = f(t + c_s h, y + h sum_j A[s, j] k_j)``."""

    name: str
    order: int
    A: np.ndarray  # (s, s), strictly lower triangular
    b: np.ndarray  # (s,)
    c: np.ndarray  # (s,)

    @classmethod
    def build(cls, name, order, A_rows, b, c):
        s = len(b)
        A = np.zeros((s, s))
        for i, row in enumerate(A_rows):
            A[i, : len(row)] = row
        tableau = cls(name, order, A, np.asarray(b, float), np.asarray(c, float))
        tableau.check()
        return tableau

    def check(self, tol=1e-14):
        """Raise AssertionError unless the tableau is explicit and consistent."""
        s = len(self.b)
        assert self.A.shape == (s, s) and self.c.shape == (s,)
        assert np.all(np.triu(self.A) == 0), f"{self.name}: A must be strictly lower triangular"
        assert np.allclose(self.A.sum(axis=1), self.c, rtol=0, atol=tol), f"{self.name}: rows of A must sum to c"
        assert abs(self.b.sum() - 1.0) < tol, f"{self.name}: b must sum to 1"


class Splitting(NamedTuple):
    """A composition of exact sub-flows: ``flows[i]`` runs for ``fractions[i] * h``."""

    name: str
    order: int
    flows: np.ndarray  # (n,) int64 sub-flow codes
    fractions: np.ndarray  # (n,) float64

    def check(self, tol=1e-14):
        for flow in np.unique(self.flows):
            total = self.fractions[self.flows == flow].sum()
            assert abs(total - 1.0) < tol, f"{self.name}: fractions of sub-flow {flow} sum to {total}, not 1"

    def without_torque(self):
        """The same method for a torque-free body: torque sub-flows dropped, neighbouring equal flows merged."""
        return _merge(self.name, self.order, [(f, x) for f, x in zip(self.flows, self.fractions) if f != TORQUE])


def _merge(name, order, sequence):
    flows, fractions = [], []
    for flow, fraction in sequence:
        if flows and flows[-1] == flow:
            fractions[-1] += fraction
        else:
            flows.append(int(flow))
            fractions.append(float(fraction))
    splitting = Splitting(name, order, np.array(flows, dtype=np.int64), np.array(fractions))
    splitting.check()
    return splitting


# Strang's symmetric second-order step: half the torque, then the three rotations palindromically.
_STRANG = [(TORQUE, 0.5), (ROTATE_1, 0.5), (ROTATE_2, 0.5), (ROTATE_3, 1.0), (ROTATE_2, 0.5), (ROTATE_1, 0.5),
           (TORQUE, 0.5)]


def compose(name, order, weights, basic=_STRANG):
    """Symmetric composition ``S(w_1 h) ... S(w_n h)`` of a basic step ``S``; adjacent equal flows merged."""
    return _merge(name, order, [(flow, w * x) for w in weights for flow, x in basic])


# First-order Lie–Trotter splitting: the "symplectic Euler" of the Lie–Poisson free rigid body.
SYMPLECTIC_EULER = _merge("symplectic_euler", 1, [(ROTATE_1, 1.0), (ROTATE_2, 1.0), (ROTATE_3, 1.0), (TORQUE, 1.0)])
SPLITTING2 = compose("splitting2", 2, [1.0])
# Suzuki's fourth-order fractal composition (M. Suzuki, Phys. Lett. A 146, 319 (1990)):
# S(g h) S(g h) S((1 - 4g) h) S(g h) S(g h), g = 1 / (4 - 4**(1/3)). Smaller error constant than Yoshida's
# three-stage "triple jump" for one more Strang step (McLachlan, SIAM J. Sci. Comput. 16, 151 (1995)).
_SUZUKI_G = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))
SPLITTING4 = compose("splitting4", 4, [_SUZUKI_G, _SUZUKI_G, 1.0 - 4.0 * _SUZUKI_G, _SUZUKI_G, _SUZUKI_G])

RK4 = ButcherTableau.build(
    "rk4", 4,
    [[], [0.5], [0.0, 0.5], [0.0, 0.0, 1.0]],
    [1 / 6, 1 / 3, 1 / 3, 1 / 6],
    [0.0, 0.5, 0.5, 1.0],
)

# Dormand & Prince's 12-stage eighth-order method, DOP853 (E. Hairer, S. P. Norsett, G. Wanner, Solving
# Ordinary Differential Equations I, 2nd ed., Springer 1993, sect. II.10), used here at a fixed step without
# its embedded error estimator. Coefficients as distributed with Hairer's dop853.f (identical to SciPy's
# scipy/integrate/_ivp/dop853_coefficients.py), to double precision.
_DOP853_C = [0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726, 0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571, 1.0]
_DOP853_B = [
    0.054293734116568765,
    0.0,
    0.0,
    0.0,
    0.0,
    4.450312892752409,
    1.8915178993145003,
    -5.801203960010585,
    0.3111643669578199,
    -0.1521609496625161,
    0.20136540080403034,
    0.04471061572777259,
]
_DOP853_A = [
    [],
    [0.05260015195876773],
    [0.0197250569845379, 0.0591751709536137],
    [0.02958758547680685, 0.0, 0.08876275643042054],
    [0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792],
    [0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242],
    [0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125],
    [0.03709200011850479, 0.0, 0.0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402, 0.008273789163814023],
    [0.6241109587160757, 0.0, 0.0, -3.3608926294469414, -0.868219346841726, 27.59209969944671, 20.154067550477894, -43.48988418106996],
    [0.47766253643826434, 0.0, 0.0, -2.4881146199716677, -0.590290826836843, 21.230051448181193, 15.279233632882423, -33.28821096898486, -0.020331201708508627],
    [-0.9371424300859873, 0.0, 0.0, 5.186372428844064, 1.0914373489967295, -8.149787010746927, -18.52006565999696, 22.739487099350505, 2.4936055526796523, -3.0467644718982196],
    [2.273310147516538, 0.0, 0.0, -10.53449546673725, -2.0008720582248625, -17.9589318631188, 27.94888452941996, -2.8589982771350235, -8.87285693353063, 12.360567175794303, 0.6433927460157636],
]

RK8 = ButcherTableau.build("rk8", 8, _DOP853_A, _DOP853_B, _DOP853_C)


class ImplicitMidpoint(NamedTuple):
    """The implicit midpoint rule: no coefficients, solved by fixed-point iteration."""

    name: str = "implicit_midpoint"
    order: int = 2


IMPLICIT_MIDPOINT = ImplicitMidpoint()

# Every fixed-step method; a method's kernel id is its index here.
ALL_METHODS = (RK4, RK8, SYMPLECTIC_EULER, SPLITTING2, SPLITTING4, IMPLICIT_MIDPOINT)

#: The explicit Runge–Kutta methods by name: what a system given by its rate runs (:mod:`tumble.kernels.loops.sample_loop`).
TABLEAUX = {m.name: m for m in ALL_METHODS if isinstance(m, ButcherTableau)}
METHOD_ORDER = tuple(m.name for m in ALL_METHODS)

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
    "ALL_METHODS", "ButcherTableau", "DOP853", "ErrorControl", "TABLEAUX", "IMPLICIT_MIDPOINT", "METHOD_ORDER", "RK4", "RK8", "SYMPLECTIC_EULER",
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


class ErrorControl(NamedTuple):
    """An explicit Runge–Kutta method with an embedded error estimate and a dense output: its tableau, whose last
    stage is evaluated at ``y1`` (``c = 1``, ``A``'s last row ``b``), and then ``f(t + h, y1)`` (the next step's
    first stage, "first same as last") as one more stage, ``k_s`` for ``s = 0 .. s``."""

    name: str
    order: int
    tableau: ButcherTableau
    error_order: int  # the order of the error estimate (the step-size control's exponent is 1 / (error_order + 1))
    e5: np.ndarray  # (s + 1,): the fifth-order estimate's weights of the stages and f(t + h, y1)
    e3: np.ndarray  # (s + 1,): the third-order estimate's
    # the third-order estimate as Hairer's code makes it, from the step's increment sum(b k): that sum less these
    # weights of these stages ((stage, weight), ...; e3 is b less them, rounded): 3 products a component, not 8
    e3_from_b: tuple
    extra_a: np.ndarray  # (3, s + 4): the dense output's three more stages (rows of A, over every stage before them)
    extra_c: np.ndarray  # (3,)
    dense: np.ndarray  # (4, s + 4): the interpolant's coefficients of degree 4 to 7 (over every stage)
    # Hairer's step-size control (dop853.f's): after a kept try the next step is h / fac, fac = err^(1/(error_order
    # + 1)) / facold^beta / safety within [1 / largest, 1 / smallest] (facold: the last kept try's error, at least
    # 1e-4; beta: the Lund stabilisation, a PI control), after a rejected one h / min(1 / smallest, err^(1/(error_order
    # + 1)) / safety)
    safety: float = 0.9
    smallest: float = 0.333
    largest: float = 6.0
    beta: float = 0.0


# DOP853's error estimates and its dense output of order 7 (Hairer, Norsett & Wanner, sect. II.6 and II.10; the
# coefficients of dop853.f, identical to SciPy's dop853_coefficients.py, which tests/test_adaptive.py compares).
_DOP853_E5 = [0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502, 1.6643771824549864, -0.35032884874997366, 0.3341791187130175, 0.08192320648511571, -0.022355307863886294, 0.0]
_DOP853_E3 = [-0.18980075407240762, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, -0.4226823213237919, -0.1521609496625161, 0.20136540080403034, 0.02265179219836082, 0.0]
_DOP853_EXTRA_C = [0.1, 0.2, 0.7777777777777778]
_DOP853_EXTRA_A = [
    [0.056167502283047954, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25350021021662483, -0.2462390374708025, -0.12419142326381637, 0.15329179827876568, 0.00820105229563469, 0.007567897660545699, -0.008298],
    [0.03183464816350214, 0.0, 0.0, 0.0, 0.0, 0.028300909672366776, 0.053541988307438566, -0.05492374857139099, 0.0, 0.0, -0.00010834732869724932, 0.0003825710908356584, -0.00034046500868740456, 0.1413124436746325],
    [-0.42889630158379194, 0.0, 0.0, 0.0, 0.0, -4.697621415361164, 7.683421196062599, 4.06898981839711, 0.3567271874552811, 0.0, 0.0, 0.0, -0.0013990241651590145, 2.9475147891527724, -9.15095847217987],
]
_DOP853_DENSE = [
    [-8.428938276109013, 0.0, 0.0, 0.0, 0.0, 0.5667149535193777, -3.0689499459498917, 2.38466765651207, 2.117034582445028, -0.871391583777973, 2.2404374302607883, 0.6315787787694688, -0.08899033645133331, 18.148505520854727, -9.194632392478356, -4.436036387594894],
    [10.427508642579134, 0.0, 0.0, 0.0, 0.0, 242.28349177525817, 165.20045171727028, -374.5467547226902, -22.113666853125306, 7.733432668472264, -30.674084731089398, -9.332130526430229, 15.697238121770845, -31.139403219565178, -9.35292435884448, 35.81684148639408],
    [19.985053242002433, 0.0, 0.0, 0.0, 0.0, -387.0373087493518, -189.17813819516758, 527.8081592054236, -11.57390253995963, 6.8812326946963, -1.0006050966910838, 0.7777137798053443, -2.778205752353508, -60.19669523126412, 84.32040550667716, 11.99229113618279],
    [-25.69393346270375, 0.0, 0.0, 0.0, 0.0, -154.18974869023643, -231.5293791760455, 357.6391179106141, 93.40532418362432, -37.45832313645163, 104.0996495089623, 29.8402934266605, -43.53345659001114, 96.32455395918828, -39.17726167561544, -149.72683625798564],
]

# dop853.f's bhh1, bhh2, bhh3, the weights of k1, k9 and k3 (its name for the twelfth stage) in ``err2``
_DOP853_E3_FROM_B = ((0, 0.244094488188976), (8, 0.733846688281611), (11, 0.0220588235294118))

# beta = 1/16 (dop853.f's default is 0; it advises up to 0.04 and keeps the err exponent at 1/8 - 0.2 beta, here 1/8, so
# that both roots are square roots, which vectorise): on 2000 spins about the intermediate axis (t = 20 s, the
# work-precision benchmark's), rejections fall by two thirds, the tries to reach a largest error of 1e-4 by a sixth
# and of 1e-12 by 4 %, and no sample's error strays far above the others' (the largest of 400 at rtol 1e-5: 8.8e-5
# against 3.6e-4)
DOP853 = ErrorControl("dop853", 8, RK8, 7, np.array(_DOP853_E5), np.array(_DOP853_E3), _DOP853_E3_FROM_B,
                      np.array([row + [0.0] * (16 - len(row)) for row in _DOP853_EXTRA_A]), np.array(_DOP853_EXTRA_C),
                      np.array(_DOP853_DENSE), beta=0.0625)
assert DOP853.e5.shape == DOP853.e3.shape == (13,) and DOP853.extra_a.shape == (3, 16) and DOP853.dense.shape == (4, 16)


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

"""Deterministic ensembles of perturbed initial spins.

A Monte Carlo scene starts from ``samples`` spins, each a steady spin about a principal axis tilted by a
small angle. :func:`perturbed_spins` draws them so that **sample ``i`` is the same number however the
ensemble is cut up**: whatever ``samples`` is, whatever slice ``[start, stop)`` a worker asks for, on any
number of threads, processes or machines.

How: the sample index space is cut into fixed chunks of :data:`CHUNK` rows. Chunk ``j`` has its own
random stream, ``numpy.random.default_rng(SeedSequence(entropy=seed, spawn_key=(j,)))`` — the same stream
as ``SeedSequence(seed).spawn(j + 1)[j]``, built without spawning the ``j`` children before it — and always
draws one full ``rng.random((CHUNK, 2))`` block, even when only a few of its rows are wanted. The block is
turned into spins by elementwise formulas on the whole chunk, and the wanted rows are cut out at the end.
So a slice of the ensemble is the same bits as the corresponding rows of the full draw.

The uniforms themselves (SeedSequence + PCG64) are the same on every platform. The spins are then made
with numpy's ``sin``, ``cos``, ``arcsin``, ``sqrt``, ``log1p``; on one numpy build and CPU family they are
bit-for-bit reproducible, across CPUs with different SIMD dispatch (AVX2 vs AVX-512) the transcendental
functions may differ in the last bit.

All three distributions use the same two uniforms per sample, ``u = (u_φ, u_θ)``: the azimuth is always
``φ = 2π u_φ`` and the tilt ``θ`` is a monotone function of ``u_θ``. Ensembles that differ only in
``amplitude`` or ``distribution`` are therefore coupled sample by sample (common random numbers), which
makes differences between scenes of a scan far less noisy than independent draws would.
"""

from __future__ import annotations

import functools
import math
import operator
from dataclasses import dataclass

import numpy as np

from .. import registry
from ..physics.bodies import finite_array, one_body
from ..physics.models import Model
from . import cost

__all__ = [
    "CHUNK",
    "CONSTRAINTS",
    "DISTRIBUTIONS",
    "chunk_count",
    "chunk_ranges",
    "drawn_spins",
    "perturbed_spins",
    "perturbed_states",
    "seed_entropy",
    "transverse_axes",
]

#: Rows per chunk of the sample index space; each chunk has its own random stream. Changing this changes
#: every ensemble ever drawn, so it is part of the reproducibility contract.
CHUNK = 4096

#: Tilt distributions understood by :func:`perturbed_spins`.
DISTRIBUTIONS = ("cone", "filled_cone", "gaussian")

#: Constraints understood by :func:`perturbed_spins` (``None``: keep ``|w| = |spin|``).
CONSTRAINTS = (None, "energy", "momentum")


def _index(value, name):
    """``value`` as a Python int (ints and numpy integers; not bools, not floats), or a ValueError."""
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    try:
        return operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be an integer, got {value!r}") from None


def _axis(axis):
    """A 1-based principal axis, validated, as a Python int."""
    try:
        a = _index(axis, "axis")
    except ValueError:
        raise ValueError(f"axis must be 1, 2 or 3 (an integer), got {axis!r}") from None
    if a not in (1, 2, 3):
        raise ValueError(f"axis must be 1, 2 or 3, got {axis!r}")
    return a


def _scalar(value, name):
    """A finite real scalar as a Python float, or a ValueError naming ``name``."""
    arr = finite_array(value, name)
    if arr.ndim != 0:
        raise ValueError(f"{name} must be a single number, got shape {arr.shape}")
    return float(arr)


def transverse_axes(axis):
    """The two axes transverse to ``axis``, in cyclic order.

    Parameters
    ----------
    axis : {1, 2, 3}
        Principal axis, 1-based.

    Returns
    -------
    (int, int)
        ``(b, c) = (a+1, a+2)`` cyclically, 1-based, so that ``(e_a, e_b, e_c)`` is right-handed.

    See Also
    --------
    tumble.sampling.perturbed_spins : Spins tilted from ``axis`` towards these two.
    tumble.theory.stability_exponent : ``q`` from the moments of ``a``, ``b`` and ``c``.

    Examples
    --------
    >>> transverse_axes(1), transverse_axes(2), transverse_axes(3)
    ((2, 3), (3, 1), (1, 2))
    """
    a = _axis(axis)
    return a % 3 + 1, (a + 1) % 3 + 1


def chunk_count(samples):
    """The number of :data:`CHUNK`-row chunks that hold an ensemble of ``samples`` (an int >= 1) spins, as an int:
    ``ceil(samples / CHUNK)``, the length of :func:`chunk_ranges`.

    See Also
    --------
    tumble.sampling.chunk_ranges : The chunks' row ranges.

    Examples
    --------
    >>> from tumble import sampling
    >>> sampling.CHUNK
    4096
    >>> sampling.chunk_count(1), sampling.chunk_count(sampling.CHUNK + 1)
    (1, 2)
    """
    n = _samples(samples)
    return -(-n // CHUNK)


def chunk_ranges(samples):
    """The ``[start, stop)`` row ranges of the chunks of an ensemble of ``samples`` spins.

    Handing one range to each worker (``perturbed_spins(..., start=start, stop=stop)``) splits the work
    along chunk boundaries, so that no chunk's random numbers are drawn twice.

    Parameters
    ----------
    samples : int
        Ensemble size, >= 1.

    Returns
    -------
    list of (int, int)
        ``chunk_count(samples)`` ranges; all but possibly the last are ``CHUNK`` long.

    See Also
    --------
    tumble.sampling.chunk_count : How many.
    tumble.sampling.perturbed_spins : Its ``start`` and ``stop``.

    Examples
    --------
    >>> from tumble import sampling
    >>> sampling.chunk_ranges(2 * sampling.CHUNK + 5)
    [(0, 4096), (4096, 8192), (8192, 8197)]
    """
    n = _samples(samples)
    return [(lo, min(lo + CHUNK, n)) for lo in range(0, n, CHUNK)]


def _samples(samples):
    n = _index(samples, "samples")
    if n < 1:
        raise ValueError(f"samples must be >= 1, got {n}")
    return n


def seed_entropy(seed=None):
    """The entropy a seed stands for: what to store so that an ensemble can be drawn again.

    Parameters
    ----------
    seed : int >= 0 or None
        ``None`` draws fresh entropy from the operating system (``numpy.random.SeedSequence().entropy``,
        a 128-bit integer).

    Returns
    -------
    int
        ``seed`` itself for an integer seed; the fresh entropy for ``None``. Passing it back as ``seed``
        reproduces the ensemble exactly. It may exceed 64 bits: store it as a string in files whose
        integer attributes are 64-bit (netCDF).

    Raises
    ------
    ValueError
        If ``seed`` is not None or a non-negative integer.

    See Also
    --------
    tumble.sampling.perturbed_spins : The ensemble a seed draws.
    tumble.io.write_dataset : Stores the entropy (``seed_entropy=``) with a result.

    Examples
    --------
    Fresh entropy, stored, draws the same ensemble again:

    >>> from tumble import sampling
    >>> sampling.seed_entropy(42)
    42
    >>> fresh = sampling.seed_entropy()
    >>> w = sampling.perturbed_spins((1.0, 2.0, 3.0), 2, samples=4, seed=fresh)
    >>> bool((sampling.perturbed_spins((1.0, 2.0, 3.0), 2, samples=4, seed=fresh) == w).all())
    True
    """
    if seed is None:
        return int(np.random.SeedSequence().entropy)
    s = _index(seed, "seed")
    if s < 0:
        raise ValueError(f"seed must be a non-negative integer or None, got {s}")
    return s


def _chunk_rng(entropy, j):
    """The random stream of chunk ``j``: identical to ``SeedSequence(entropy).spawn(j + 1)[j]``."""
    return np.random.default_rng(np.random.SeedSequence(entropy=entropy, spawn_key=(j,)))


def _tilt(u_theta, distribution, amplitude):
    """Tilt angle θ, rad, shape (m,), from uniforms ``u_theta`` in [0, 1)."""
    if distribution == "cone":
        return np.full(u_theta.shape, amplitude)
    if distribution == "filled_cone":
        # Uniform in solid angle on the cap θ <= α: 1 − cos θ = u (1 − cos α). Written with half angles,
        # 2 sin²(θ/2) = 2 u sin²(α/2), so that tiny caps keep full relative precision.
        return 2.0 * np.arcsin(np.sqrt(u_theta) * math.sin(0.5 * amplitude))
    # "gaussian": two independent N(0, α²) tilt components in polar form (Box–Muller): the norm is
    # Rayleigh, r = α sqrt(−2 ln(1 − u)), the direction is the uniform azimuth. 1 − u is in (0, 1].
    return amplitude * np.sqrt(-2.0 * np.log1p(-u_theta))


def _unit_directions(u, axis, distribution, amplitude):
    """Unit vectors, shape (m, 3): ``cos θ e_a + sin θ (cos φ e_b + sin φ e_c)``."""
    theta = _tilt(u[:, 1], distribution, amplitude)
    phi = (2.0 * np.pi) * u[:, 0]
    s = np.sin(theta)
    a = axis - 1
    out = np.empty((u.shape[0], 3))
    out[:, a] = np.cos(theta)
    out[:, (a + 1) % 3] = s * np.cos(phi)
    out[:, (a + 2) % 3] = s * np.sin(phi)
    return out


@functools.lru_cache(maxsize=32)
def _chunk_directions(entropy, j, axis, distribution, amplitude):
    """The unit directions of chunk ``j`` (read-only, shape (CHUNK, 3)), kept for reuse: the scenes of a scan share
    their seed (common random numbers), so every scene about the same axis with the same tilt draws the same
    directions; drawing and transforming a chunk costs far more than the scene's use of it."""
    u = _chunk_rng(entropy, j).random((CHUNK, 2))
    directions = _unit_directions(u, axis, distribution, amplitude)
    directions.flags.writeable = False
    return directions


def _constraint_scale(directions, moments, axis, constraint):
    """Factor, shape (m,), that rescales ``spin * directions`` onto the constraint surface."""
    # Plain elementwise arithmetic (no BLAS), so the result is the same bits on every run.
    ia = moments[axis - 1]
    u1, u2, u3 = directions[:, 0], directions[:, 1], directions[:, 2]
    i1, i2, i3 = moments
    if constraint == "energy":
        # ½ Σ Ii (s w ui)² = ½ Ia w²  →  s = sqrt(Ia / Σ Ii ui²)
        return np.sqrt(ia / (i1 * u1 * u1 + i2 * u2 * u2 + i3 * u3 * u3))
    # |L| = |s w| sqrt(Σ (Ii ui)²) = Ia |w|  →  s = Ia / |I u|
    return ia / np.sqrt((i1 * u1) ** 2 + (i2 * u2) ** 2 + (i3 * u3) ** 2)


def perturbed_spins(body, axis, spin=1.0, amplitude=1e-3, samples=1024, *, seed=0, distribution="cone",
                    constraint=None, start=0, stop=None, return_entropy=False):
    # size: a public call: each keyword is a documented sampling option (distribution, constraint, sample range)
    """Steady spins about a principal axis, each tilted by a small random angle; reproducible by index.

    Sample ``i`` is ``w_i = spin · s_i (cos θ_i e_a + sin θ_i (cos φ_i e_b + sin φ_i e_c))`` with
    ``(b, c) = transverse_axes(axis)``, the azimuth ``φ_i`` uniform in [0, 2π), the tilt ``θ_i`` drawn
    from ``distribution``, and ``s_i = 1`` unless a ``constraint`` rescales it. A negative ``spin`` gives
    exactly ``−w_i`` (spins about ``−e_a``).

    Sample ``i`` depends only on ``(seed, i, axis, spin, amplitude, distribution, constraint, body)``,
    never on ``samples``, ``start`` or ``stop``: ``perturbed_spins(..., start=a, stop=b)`` is bit for bit
    ``perturbed_spins(...)[a:b]``, and draws only the :data:`CHUNK`-row chunks that cover ``[a, b)``
    (see the module docstring).

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        Principal moments, kg m² (used by the constraints; always validated).
    axis : {1, 2, 3}
        Principal axis of the unperturbed spin, 1-based.
    spin : float
        Unperturbed spin rate about ``axis``, rad/s; finite, non-zero, either sign.
    amplitude : float
        Tilt scale α, rad; finite, >= 0, and < π/2 for ``"cone"`` and ``"filled_cone"``.
    samples : int
        Size of the whole ensemble, >= 1.
    seed : int >= 0 or None
        Entropy of the ensemble. ``None`` draws fresh entropy (see :func:`seed_entropy`; pass
        ``return_entropy=True`` to get it back for provenance).
    distribution : {"cone", "filled_cone", "gaussian"}
        * ``"cone"``: ``θ = α`` exactly, the rim of the cone of half-angle α;
        * ``"filled_cone"``: uniform in solid angle over the cap ``θ <= α``
          (``cos θ`` uniform in ``[cos α, 1]``);
        * ``"gaussian"``: the two transverse tilt components ``(θ cos φ, θ sin φ)`` are independent
          normals of standard deviation α (``θ`` is Rayleigh distributed, unbounded).
    constraint : {None, "energy", "momentum"}
        * ``None``: ``|w_i| = |spin|``;
        * ``"energy"``: rescale so that ``½ Σ Ij w_ij² = ½ I_a spin²``, the kinetic energy of the
          unperturbed spin;
        * ``"momentum"``: rescale so that ``|L_i| = |Σ Ij w_ij e_j| = I_a |spin|``.

        The direction of each spin is unchanged by the rescaling.
    start, stop : int
        Rows ``[start, stop)`` of the ensemble to return; ``0 <= start <= stop <= samples``;
        ``stop=None`` means ``samples``.
    return_entropy : bool
        Also return the entropy actually used (``seed_entropy(seed)``).

    Returns
    -------
    spins : ndarray, shape (stop − start, 3), float64
        Body-frame angular velocities, rad/s, C-contiguous.
    entropy : int
        Only with ``return_entropy=True``: the seed to store to draw the same spins again.

    Raises
    ------
    ValueError
        Invalid body, an axis other than 1, 2, 3, a zero or non-finite spin, an amplitude out of range,
        ``samples < 1`` or not an integer, an unknown distribution or constraint, ``start``/``stop`` out of
        range, or a seed that is not a non-negative integer or None.

    See Also
    --------
    tumble.sampling.perturbed_states : The same for a model's whole state.
    tumble.sampling.chunk_ranges : Slices that split the ensemble between workers.
    tumble.measure : A scene measured on such an ensemble.

    Examples
    --------
    >>> w = perturbed_spins((1.0, 2.0, 3.0), 2, spin=2.0, amplitude=0.01, samples=8)
    >>> w.shape
    (8, 3)
    >>> np.allclose(np.linalg.norm(w, axis=1), 2.0)
    True
    >>> np.array_equal(perturbed_spins((1.0, 2.0, 3.0), 2, 2.0, 0.01, 8, start=3, stop=5), w[3:5])
    True
    """
    moments = one_body(body)
    axis = _axis(axis)
    spin = _scalar(spin, "spin")
    if spin == 0.0:
        raise ValueError("spin must be non-zero (a steady spin about the axis), got 0")
    low, high = registry.SPIN_RANGE
    if not low <= abs(spin) <= high:
        raise ValueError(f"spin must be within {low:g} to {high:g} rad/s in magnitude, got {spin!r}: beyond, squares "
                         f"leave the float range; the motion is scale invariant (w rad/s is 1 rad/s with times / w)")
    if not isinstance(distribution, str) or distribution not in DISTRIBUTIONS:
        raise ValueError(f"distribution must be one of {', '.join(map(repr, DISTRIBUTIONS))}; "
                         f"got {distribution!r}")
    if constraint is not None and (not isinstance(constraint, str) or constraint not in CONSTRAINTS):
        raise ValueError(f"constraint must be one of {', '.join(map(repr, CONSTRAINTS))}; got {constraint!r}")
    amplitude = _scalar(amplitude, "amplitude")
    if amplitude < 0:
        raise ValueError(f"amplitude must be >= 0 rad, got {amplitude}")
    if distribution != "gaussian" and amplitude >= 0.5 * np.pi:
        raise ValueError(f"amplitude must be < π/2 rad for distribution {distribution!r} (a tilt that small "
                         f"keeps every spin on the axis's side), got {amplitude}")
    n = _samples(samples)
    start = _index(start, "start")
    stop = n if stop is None else _index(stop, "stop")
    if not 0 <= start <= n:
        raise ValueError(f"start must be in [0, samples] = [0, {n}], got {start}")
    if not start <= stop <= n:
        raise ValueError(f"stop must be in [start, samples] = [{start}, {n}], got {stop}")
    cost.refuse(cost.run_cost(stop - start, 0, 3),
                f"samples = {n}" if (start, stop) == (0, n) else f"start, stop = {start}, {stop}")
    entropy = seed_entropy(seed)
    out = drawn_spins(moments, axis, spin, amplitude, entropy, distribution, start, stop, constraint)
    return (out, entropy) if return_entropy else out


def drawn_spins(moments, axis, spin, amplitude, entropy, distribution, start, stop, constraint=None):
    # size: perturbed_spins' arguments once checked (the values a Scene holds), and the sample range
    """Rows ``[start, stop)`` of :func:`perturbed_spins` from arguments it has already checked (moments (3,), axis
    1-3, Python floats, the entropy of :func:`seed_entropy`): the same bits, without the checks, which cost ten times
    the drawing of a slice a scan already drew (a scene planned from checked options draws its slices here)."""
    out = np.empty((stop - start, 3))
    chunks = range(start // CHUNK, -(-stop // CHUNK)) if stop > start else range(0)
    for j in chunks:
        lo, hi = j * CHUNK, (j + 1) * CHUNK
        # Always the whole chunk's block of uniforms, and the whole chunk's transform: the rows kept are
        # then the same bits however the ensemble is sliced.
        directions = _chunk_directions(entropy, j, axis, distribution, amplitude)
        if constraint is not None:
            directions = directions * _constraint_scale(directions, moments, axis, constraint)[:, None]
        keep_lo, keep_hi = max(lo, start), min(hi, stop)
        out[keep_lo - start:keep_hi - start] = spin * directions[keep_lo - lo:keep_hi - lo]
    return out


#: The spawn key of the stream that tilts a heavy top's up vector: two entries, so it is none of the chunks' keys
#: ``(j,)`` of :func:`perturbed_spins`, and the tilt of ``g`` is independent of the tilt of the spin.
_UP_SPAWN_KEY = (0, 1)


def _up_entropy(entropy):
    """The entropy of the up vector's tilts, derived from the ensemble's (deterministic, 128 bits)."""
    words = np.random.SeedSequence(entropy, spawn_key=_UP_SPAWN_KEY).generate_state(4, np.uint32)
    return sum(int(word) << (32 * i) for i, word in enumerate(words))


#: The spawn key of the streams that tilt a gravity-gradient satellite's attitude: chunk ``j`` draws from
#: ``SeedSequence(entropy, spawn_key=(j, 2))`` (two entries: none of :func:`perturbed_spins`' chunk keys ``(j,)``,
#: nor the up vector's ``(0, 1)``).
_ATTITUDE_SPAWN = 2


@functools.lru_cache(maxsize=32)
def _chunk_attitudes(entropy, j, distribution, amplitude):
    """Chunk ``j``'s attitudes (CHUNK, 4), read-only: ``(cos(θ/2), sin(θ/2) u)``, ``u`` uniform on the sphere,
    ``θ`` the tilt.

    One ``rng.random((CHUNK, 3))`` block per chunk, always whole (slices are then the same bits): ``u`` from the
    first two uniforms (``u3 = 1 − 2 v``, azimuth ``2π v'``), ``θ`` from the third by :func:`_tilt` (a monotone
    function of it: ensembles that differ only in ``amplitude`` are coupled sample by sample). Kept for reuse, as
    :func:`_chunk_directions`: the attitudes do not depend on the body, and every scene of a gravity-gradient scan
    draws the same ones (a DeBra-Delp map's 1600 scenes drew the same chunk 3200 times)."""
    v = np.random.default_rng(np.random.SeedSequence(entropy=entropy, spawn_key=(j, _ATTITUDE_SPAWN))).random(
        (CHUNK, 3))
    z = 1.0 - 2.0 * v[:, 0]
    r = np.sqrt(np.maximum(0.0, (1.0 - z) * (1.0 + z)))
    phi = (2.0 * np.pi) * v[:, 1]
    half = 0.5 * _tilt(v[:, 2], distribution, amplitude)
    s = np.sin(half)
    attitudes = np.stack([np.cos(half), s * r * np.cos(phi), s * r * np.sin(phi), s * z], axis=-1)
    attitudes.flags.writeable = False
    return attitudes


def _tilted_attitudes(amplitude, samples, entropy, distribution, start, stop):
    """Rows ``[start, stop)`` of an ensemble's tilted attitudes (unit quaternions, scalar first), shape (N, 4)."""
    if stop is None:
        stop = samples
    out = np.empty((stop - start, 4))
    chunks = range(start // CHUNK, -(-stop // CHUNK)) if stop > start else range(0)
    for j in chunks:
        lo = j * CHUNK
        keep_lo, keep_hi = max(lo, start), min(lo + CHUNK, stop)
        out[keep_lo - start:keep_hi - start] = _chunk_attitudes(entropy, j, distribution, amplitude)[keep_lo - lo:
                                                                                                     keep_hi - lo]
    return out


@dataclass
class _Draws:
    """The random parts of rows ``[start, stop)`` of a model's ensemble, each drawn when the model asks for it
    (:meth:`tumble.physics.models.Model.perturbed`), from the arguments of :func:`perturbed_states`."""

    moments: np.ndarray
    axis: int
    spin: float
    amplitude: float
    samples: int
    up_amplitude: float | None
    seed: int | None
    distribution: str
    start: int
    stop: int | None
    entropy: int | None = None  # the ensemble's, once the spins are drawn

    def _spins(self, axis, spin):
        w, self.entropy = perturbed_spins(self.moments, axis, spin, self.amplitude, self.samples, seed=self.seed,
                                          distribution=self.distribution, start=self.start, stop=self.stop,
                                          return_entropy=True)
        return w

    def spins(self):
        """The steady spin tilted by ``amplitude`` (:func:`perturbed_spins`), shape (N, 3), rad/s."""
        return self._spins(self.axis, self.spin)

    def up(self):
        """A heavy top's up vector: ``e3`` tilted by ``up_amplitude`` (default ``amplitude``), the same distribution,
        a random stream derived from the ensemble's entropy (independent of the spins' tilts), shape (N, 3)."""
        if self.entropy is None:
            self.spins()
        tilt = self.amplitude if self.up_amplitude is None else _scalar(self.up_amplitude, "up_amplitude")
        return perturbed_spins(self.moments, 3, 1.0, tilt, self.samples, seed=_up_entropy(self.entropy),
                               distribution=self.distribution, start=self.start, stop=self.stop)

    def attitudes(self):
        """Attitudes tilted by ``amplitude`` (the distribution's angle ``θ``: exactly ``amplitude`` for ``"cone"``)
        about a uniformly random axis ``u``, ``q = (cos(θ/2), sin(θ/2) u)``, shape (N, 4): their own stream of the
        seed. The sampling arguments are checked (and the seed's entropy drawn) as for the spins, which are not used."""
        self._spins(3, 1.0)
        return _tilted_attitudes(self.amplitude, self.samples, self.entropy, self.distribution, self.start, self.stop)


def perturbed_states(model, axis, spin=1.0, amplitude=1e-3, samples=1024, *, up_amplitude=None, seed=0,
                     distribution="cone", start=0, stop=None):
    # size: a public call: each keyword is a documented sampling option (the up vector's tilt, the sample range)
    """States of a model near its steady spin about ``axis``, each tilted by small random angles; reproducible by
    index.

    The angular velocity is :func:`perturbed_spins` of the model's moments (no constraint): the steady spin tilted
    by ``amplitude``. A heavy top's up vector ``g`` (its state's components 3-5) is ``e3`` tilted by an
    independent angle of scale ``up_amplitude`` (the same distribution, a random stream derived from the seed).
    A damper's sphere moves with the body: ``s = w``. A gravity-gradient satellite's attitude relative to the orbit
    frame is tilted by ``amplitude`` (the distribution's angle ``θ``: exactly ``amplitude`` for ``"cone"``) about a
    uniformly random axis ``u``, ``q = (cos(θ/2), sin(θ/2) u)``, and its ``w`` is the orbit frame's rate at that
    attitude, ``w = −n c2`` (:meth:`~tumble.physics.models.GravityGradient.following_velocity`: the body does not
    turn relative to the orbit frame at first); ``axis`` and ``spin`` are not used (checked as by its
    :meth:`~tumble.physics.models.GravityGradient.equilibrium`), the draw is its own stream of the seed.
    Other components are the equilibrium's (:meth:`tumble.physics.models.Model.equilibrium`). As for
    :func:`perturbed_spins`, sample ``i`` depends only on the seed, ``i`` and the physical arguments:
    ``start``/``stop`` give bit for bit the rows of the whole draw.

    Parameters
    ----------
    model : tumble.physics.models.Model
        A free body, gyrostat, heavy top, gravity-gradient satellite or body with a damper.
    axis : {1, 2, 3}
        The steady spin's axis, 1-based (a heavy top: 3; a gyrostat: the axis its rotor lies along).
    spin : float
        The steady spin rate, rad/s; finite, non-zero.
    amplitude : float
        Tilt scale of the spin, rad (see :func:`perturbed_spins`).
    samples : int
        Size of the whole ensemble, >= 1.
    up_amplitude : float, optional
        Tilt scale of a heavy top's up vector, rad; default ``amplitude``. Ignored by the other models.
    seed : int >= 0 or None
        Entropy of the ensemble (``None``: fresh entropy).
    distribution : {"cone", "filled_cone", "gaussian"}
        The tilts' distribution (:func:`perturbed_spins`).
    start, stop : int
        Rows ``[start, stop)`` of the ensemble to return.

    Returns
    -------
    ndarray, shape (stop − start, model.state_size), float64
        States: ``w`` (rad/s), then the model's own components.

    Raises
    ------
    ValueError
        ``model`` is not a model; an axis the model has no steady spin about; any argument
        :func:`perturbed_spins` refuses (named in the message).

    See Also
    --------
    tumble.sampling.perturbed_spins : The spins alone, of a free body.
    tumble.models.HeavyTop : A model whose state goes beyond the spin.

    Examples
    --------
    A sleeping top's states, its spin and its up vector tilted by about 1 mrad:

    >>> import tumble
    >>> from tumble import sampling
    >>> top = tumble.models.HeavyTop((1.0, 1.0, 0.5), 0.1)
    >>> y0 = sampling.perturbed_states(top, 3, spin=5.0, samples=4)
    >>> y0.shape, top.spec.state
    ((4, 6), ('w1', 'w2', 'w3', 'g1', 'g2', 'g3'))
    >>> bool(abs(y0[:, 2] - 5.0).max() < 1e-5)
    True
    """
    if not isinstance(model, Model):
        raise ValueError(f"model must be a tumble.physics.models model (FreeBody, Gyrostat, HeavyTop, "
                         f"GravityGradient, Damper), got {type(model).__name__}")
    # the model says which draws its state takes (Model.perturbed); each is drawn here
    draws = _Draws(model.moments, axis, spin, amplitude, samples, up_amplitude, seed, distribution, start, stop)
    return model.perturbed(draws, axis, spin)

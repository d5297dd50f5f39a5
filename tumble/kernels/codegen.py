"""Generate :mod:`tumble.kernels.fused` from the coefficient tables in :mod:`tumble.kernels.tableaux`.

The fastest layout keeps one sample's whole step in registers and lets the compiler vectorise the loop over
the samples of a block. That needs every stage spelled out with its coefficients as literals, so the
per-sample step functions are generated from the tables, which stay the single source of truth; a test
checks that the committed module is what this generator writes. Regenerate with::

    python tumble/kernels/codegen.py

(run as a script it needs only :mod:`tableaux`, so it works even when ``fused.py`` is missing or broken).
"""

from pathlib import Path

if __package__:
    from . import tableaux
else:  # run as a script: import the tables beside this file without importing the tumble package
    import tableaux

METHOD_ORDER = tableaux.METHOD_ORDER

TARGET = Path(__file__).with_name("fused.py")
_COMPONENTS = ("w1", "w2", "w3")
# body_constants index of I_c/I_b and I_b/I_c for a rotation about axis a (0-based), (a, b, c) cyclic.
_RATIOS = {0: (9, 11), 1: (10, 7), 2: (6, 8)}
_TORQUE_ARGS = "torque_kind, torque_params, torque_fn"


def _combination(base, terms, component):
    """``base + ((c0 * h) * k1_x + ...)`` over the non-zero terms, coefficients as exact literals.

    Each ``(c * h)`` is loop-invariant, so every term is one fused multiply-add; the increment is summed
    before it is added to ``base`` (less round-off than accumulating into the state, and as fast, measured).
    """
    parts = [f"({float(coef)!r} * h) * k{j + 1}_{component}" for j, coef in terms if coef != 0.0]
    return f"{base} + ({' + '.join(parts)})" if parts else base


def explicit_rk_source(tableau):
    """Source of ``<name>_sample(w1, w2, w3, t, h, body, torque...)`` for an explicit Runge–Kutta method."""
    lines = [
        "@jit(inline=True)",
        f"def {tableau.name}_sample(w1, w2, w3, t, h, body, {_TORQUE_ARGS}):",
        f'    """One step of {tableau.name} (order {tableau.order}, {len(tableau.b)} stages) for one sample."""',
    ]
    for s in range(len(tableau.b)):
        time = "t" if tableau.c[s] == 0.0 else f"t + {float(tableau.c[s])!r} * h"
        lines.append(f"    k{s + 1}_1, k{s + 1}_2, k{s + 1}_3 = euler_rate(")
        lines.append(f"        {time},")
        for i, w in enumerate(_COMPONENTS):
            lines.append(f"        {_combination(w, enumerate(tableau.A[s, :s]), i + 1)},")
        lines.append(f"        body, {_TORQUE_ARGS})")
    lines.append("    return (")
    for i, w in enumerate(_COMPONENTS):
        lines.append(f"        {_combination(w, enumerate(tableau.b), i + 1)},")
    lines.append("    )")
    return "\n".join(lines)


def splitting_source(splitting, name):
    """Source of ``name(w1, w2, w3, t, h, body, target, torque...)`` for a torque-free composition of exact
    sub-flows, spelled out (the loop over a block vectorises across samples)."""
    assert tableaux.TORQUE not in splitting.flows, "torque compositions run as a loop (splitting_with_torque)"
    lines = [
        "@jit(inline=True)",
        f"def {name}(w1, w2, w3, t, h, body, target, {_TORQUE_ARGS}):",
        f'    """One step of {splitting.name} (order {splitting.order}) for one sample, torque-free: ends on the '
        f'sample\'s own |L|**2."""',
    ]
    for flow, fraction in zip(splitting.flows, splitting.fractions):
        tau = f"{float(fraction)!r} * h"
        a = int(flow)  # ROTATE_1..3 are axes 0..2 of the kernel frame
        wa, wb, wc = _COMPONENTS[a], _COMPONENTS[(a + 1) % 3], _COMPONENTS[(a + 2) % 3]
        r_cb, r_bc = _RATIOS[a]
        lines.append(f"    {wb}, {wc} = rotate({wa} * ({tau}), {wb}, {wc}, body[{r_cb}], body[{r_bc}])")
    lines.append("    return project_l_squared(w1, w2, w3, target, body)")
    return "\n".join(lines)


def composition_source(splitting):
    """The composition of ``splitting`` (torque sub-flows included) as two constant arrays, for the loop of
    :func:`tumble.kernels.steppers.splitting_with_torque`."""
    prefix = f"_{splitting.name.upper()}"
    flows = ", ".join(str(int(f)) for f in splitting.flows)
    fractions = ", ".join(repr(float(x)) for x in splitting.fractions)
    return "\n".join([f"{prefix}_FLOWS = np.array([{flows}], dtype=np.int64)",
                      f"{prefix}_FRACTIONS = np.array([{fractions}])"])


def _sample_loop(call, indent):
    """Loop over the block, every sample stepped (the driver restores the ones that have stopped, which keeps
    this loop free of selects: a select per sample halves its SIMD throughput, measured)."""
    pad = " " * indent
    return [
        f"{pad}for i in range(n):",
        f"{pad}    y1[i], y2[i], y3[i] = {call}",
    ]


def module_source():
    """The whole text of :mod:`tumble.kernels.fused`."""
    methods = {m.name: m for m in tableaux.ALL_METHODS}
    blocks = [
        '"""Per-sample steps of every explicit fixed-step method, and the loop over a block for each.',
        "",
        "GENERATED by ``python tumble/kernels/codegen.py`` from :mod:`tumble.kernels.tableaux`; do not edit.",
        '"""',
        "",
        "import numpy as np",
        "",
        "from .jit import jit",
        "from .steppers import euler_rate, project_l_squared, rotate, splitting_with_torque",
        "",
    ]
    sample_call = "y1[i], y2[i], y3[i], t, h, body"
    signature = f"(y1, y2, y3, active, t, h, body, target, work, {_TORQUE_ARGS})"
    for name in METHOD_ORDER:
        method = methods[name]
        if isinstance(method, tableaux.ImplicitMidpoint):
            continue  # the implicit midpoint rule is a hand-written block function (steppers.py)
        if isinstance(method, tableaux.ButcherTableau):
            blocks += ["", "", explicit_rk_source(method)]
            body = _sample_loop(f"{name}_sample({sample_call}, {_TORQUE_ARGS})", 4)
        else:
            # With a torque the sub-flows run as a loop over the composition: the step is bound by the torque
            # calls anyway, and the spelled-out form took minutes to compile (splitting4: 110 s against 2 s,
            # the same bits and the same speed, measured).
            prefix = f"_{name.upper()}"
            blocks += ["", "", splitting_source(method.without_torque(), f"{name}_free_sample")]
            blocks += ["", composition_source(method)]
            body = ["    if torque_params is None:"]
            body += _sample_loop(f"{name}_free_sample({sample_call}, target[i], {_TORQUE_ARGS})", 8)
            body.append("    else:")
            body += _sample_loop(f"splitting_with_torque({sample_call}, {prefix}_FLOWS, {prefix}_FRACTIONS, "
                                 f"{_TORQUE_ARGS})", 8)
        blocks += [
            "",
            "",
            "@jit",
            f"def {name}_block{signature}:",
            f'    """Advance every sample of a block by one {name} step."""',
            "    n = y1.shape[0]",
            *body,
        ]
    blocks.append("")
    return "\n".join(blocks)


def main():
    TARGET.write_text(module_source())
    print(f"wrote {TARGET}")


if __name__ == "__main__":
    main()

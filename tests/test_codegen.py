"""The generated per-sample kernels are exactly what the coefficient tables say."""

from pathlib import Path

from tumble.kernels.steps import codegen
from tumble.kernels import tableaux


def test_committed_fused_module_is_what_the_generator_writes():
    committed = Path(codegen.TARGET).read_text()
    assert committed == codegen.module_source(), "run: python -m tumble.kernels.steps.codegen"


def test_every_nonzero_coefficient_appears_as_an_exact_literal():
    source = codegen.module_source()
    for tableau in (tableaux.RK4, tableaux.RK8):
        for value in [*tableau.A[tableau.A != 0], *tableau.b[tableau.b != 0]]:
            assert f"({float(value)!r} * h)" in source
    for splitting in (tableaux.SPLITTING2, tableaux.SPLITTING4):
        free = splitting.without_torque()
        prefix = f"_{splitting.name.upper()}_FREE"
        assert f"{prefix}_FLOWS = np.array([{', '.join(str(int(f)) for f in free.flows)}], dtype=np.int64)" in source
        assert f"{prefix}_FRACTIONS = np.array([{', '.join(repr(float(x)) for x in free.fractions)}])" in source

"""The stored numbers against every vector width this machine can compile for.

    python tests/data/bundled/widths.py            # every bundled study (several minutes: two cold compiles)
    python tests/data/bundled/widths.py NAME ...   # only these

``tests/test_bundled_results.py`` holds a run to the stored files bit for bit on a machine of their vector width and
to ``across_vector_widths`` elsewhere; CI's machines have one width. This script runs the small studies once per
width (AVX2 always, AVX-512 where the CPU has it: numba compiles for AVX2 on an AVX-512 machine when told
``NUMBA_CPU_NAME`` and ``NUMBA_CPU_FEATURES`` without AVX-512), each in its own process with its own numba cache,
and prints, for each study and width, whether the run equals the stored file and the other width's run to the bit
and the largest share of the cross-width tolerance a difference from the stored file uses (1.0 = at the tolerance).
It exits 1 when a difference passes its tolerance.

What it showed on an AVX-512 machine (AMD EPYC, znver4, 2 cores, 2026-12-06; the stored files made on AVX2 but for
dzhanibekov_flip): every study within 0.069 of the tolerance (explorer1's ``fit_norm_stop``; the chaos studies'
exponents 0.003). The runs compiled for AVX2 there were the same bits as AVX-512's in every study but explorer1, and
where they differ from the stored files they differ alike: what moves those bits is the machine as much as the width
numba compiles for, so a stored file is held to the bit only on the machine kind it was made on.
"""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2]))
sys.path.insert(0, str(HERE.parents[1]))

import test_bundled_results as bundled  # noqa: E402

# A Zen 3 core: FMA and AVX2, no AVX-512 (LLVM's own name; its features are the host's less AVX-512's).
AVX2_CPU = os.environ.get("TUMBLE_AVX2_CPU", "znver3")


def width_environments():
    """{width: environment variables} for each vector width this machine can run."""
    import llvmlite.binding as llvm

    features = llvm.get_host_cpu_features()
    widths = {}
    if features.get("avx512f"):
        widths["avx512"] = {}
        avx2 = ",".join(("-" if name.startswith("avx512") else "+" if on else "-") + name
                        for name, on in sorted(features.items()))
        # numpy dispatches its own loops (log, exp, sums) on the CPU's features too: AVX-512's off for it as well
        widths["avx2"] = {"NUMBA_CPU_NAME": AVX2_CPU, "NUMBA_CPU_FEATURES": avx2,
                          "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"}
    elif features.get("avx2"):
        widths["avx2"] = {}
    return widths


def run_width(names, env, out, cache):
    """Run the small studies in a new process compiled for one width; their results land in ``out``."""
    code = (
        "import sys; sys.path[:0] = [{tests!r}, {root!r}]\n"
        "import test_bundled_results as b\n"
        "for name in {names!r}:\n"
        "    ds = b.run_small(name); ds.attrs['stored_on'] = b.machine_signature()\n"
        "    ds.to_netcdf({out!r} + '/' + name + '.nc')\n"
    ).format(tests=str(HERE.parents[1]), root=str(HERE.parents[2]), names=list(names), out=str(out))
    subprocess.run([sys.executable, "-c", code], env={**os.environ, **env, "NUMBA_CACHE_DIR": str(cache)},
                   check=True)


def share_of_tolerance(got, stored):
    """{variable: largest |got - stored| / (atol + rtol |stored|)} over the float variables that differ."""
    shares = {}
    for var in stored.variables:
        a, b = got[var].values, stored[var].values
        if a.dtype.kind not in "fc" or np.array_equal(a, b, equal_nan=True):
            continue
        tol = bundled.across_vector_widths(var, stored)
        with np.errstate(invalid="ignore"):
            ratio = np.abs(a - b) / (tol["atol"] + tol["rtol"] * np.abs(b))
        shares[var] = float(np.nanmax(ratio, initial=0.0))
    return shares


def same_bits(got, stored):
    return all(np.array_equal(got[v].values, stored[v].values, equal_nan=got[v].dtype.kind in "fc")
               for v in stored.variables)


def yesno(flag):
    return "yes" if flag else "no"


def main(names=()):
    names = list(names) or bundled.STUDIES
    widths = width_environments()
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        for width, env in widths.items():
            out, cache = Path(tmp, width), Path(tmp, width + "-cache")
            out.mkdir()
            print(f"running {len(names)} studies compiled for {width} ...", flush=True)
            run_width(names, env, out, cache)
        print(f"\n{'study':24} {'width':7} {'stored on':10} {'stored bits':11} {'bits of the other width':23} "
              "largest share of the tolerance (variable)")
        for name in names:
            stored = xr.load_dataset(HERE / f"{name}.nc")
            stored_on = stored.attrs.pop("stored_on").split()[-1]
            runs = {width: xr.load_dataset(Path(tmp, width, f"{name}.nc")).drop_attrs() for width in widths}
            for width, got in runs.items():
                others = [same_bits(got, run) for w, run in runs.items() if w != width]
                shares = share_of_tolerance(got, stored)
                var, share = max(shares.items(), key=lambda kv: kv[1], default=("", 0.0))
                print(f"{name:24} {width:7} {stored_on:10} {yesno(same_bits(got, stored)):11} "
                      f"{yesno(all(others)) if others else '-':23} {share:.3g}" + (f" ({var})" if var else ""))
                failed |= share > 1.0
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

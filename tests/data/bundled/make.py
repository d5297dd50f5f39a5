"""Store the results of the bundled studies, run small, that ``tests/test_bundled_results.py`` compares against.

    python tests/data/bundled/make.py            # rewrites tests/data/bundled/<study>.nc
    python tests/data/bundled/make.py NAME ...   # rewrites only the named studies' files (a new study)

Run it only when a change is *meant* to change results, and say so in the commit: the stored files are the
guard that a refactoring (a new layout, fewer compiled variants, a batched path) leaves every number as it was.
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2]))  # the checkout's tumble, also when run from elsewhere
sys.path.insert(0, str(HERE.parents[1]))

import test_bundled_results as bundled  # noqa: E402


def main(names=()):
    unknown = sorted(set(names) - set(bundled.STUDIES))
    if unknown:
        raise SystemExit(f"not bundled studies: {', '.join(unknown)} (bundled: {', '.join(bundled.STUDIES)})")
    for name in names or bundled.STUDIES:
        ds = bundled.run_small(name)
        ds.attrs["stored_on"] = bundled.machine_signature()
        path = HERE / f"{name}.nc"
        ds.to_netcdf(path.with_suffix(".part"))
        path.with_suffix(".part").replace(path)
        print(f"wrote {path.relative_to(HERE.parents[2])} ({path.stat().st_size // 1024} KiB)")


if __name__ == "__main__":
    main(sys.argv[1:])

"""The README's two commands as a newcomer meets them: what each runs and what it costs, cold and warm.

    python benchmarks/suite.py             # about 12 min on 2 cores: the cold runs compile every kernel
    python benchmarks/suite.py --quick     # the warm runs only, on the cache as it is

Each command runs in a new process from the repository's root, with the interpreter that runs this script:

* **cold**: numba's disk cache in an empty folder (``NUMBA_CACHE_DIR``), as after a fresh install: ``tumble run`` (the
  default study, its first run, which compiles its kernels), then ``python -m pytest`` (the default test set, which
  compiles what the study did not), in the README's order;
* **warm**: both again on that cache.

The install (``pip install``) is not timed: it depends on the package index and the network (``fresh-check`` runs the
whole Quickstart from a clone). Time nothing else on the machine meanwhile. Writes ``benchmarks/results/suite.json``
and ``suite.md``.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import provenance

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
#: What each command of the README's Quickstart runs.
COMMANDS = {
    "tumble run": "the default study: 2 048 spins of a T-handle tilted 1 mrad from its intermediate axis, their growth "
                  "rate against linear theory and their flips",
    "python -m pytest": "the default tests on two worker processes",
}
_SUMMARY = re.compile(r"(\d+) (passed|failed|skipped|errors?|deselected|xfailed|xpassed)")


def timed(command, env, out):
    """``(seconds, its last line)`` of ``command`` (a key of :data:`COMMANDS`) run once in a new process; a failing
    command stops the benchmark with its output."""
    argv = ([sys.executable, "-m", "tumble", "run", "--out", str(out)] if command == "tumble run"
            else [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"])
    started = time.perf_counter()
    done = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"{command} failed (exit {done.returncode}):\n{done.stdout[-4000:]}\n{done.stderr[-4000:]}")
    lines = [line for line in done.stdout.splitlines() if line.strip()]
    return seconds, lines[-1] if lines else ""


def counts(line):
    """pytest's closing line as ``{"passed": N, ...}``."""
    return {kind.rstrip("s") if kind.startswith("error") else kind: int(n) for n, kind in _SUMMARY.findall(line)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the warm runs only, on the cache as it is")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    rows = {command: {"runs": text} for command, text in COMMANDS.items()}
    with tempfile.TemporaryDirectory(prefix="tumble-suite-") as scratch:
        env = dict(os.environ)
        if not args.quick:
            env["NUMBA_CACHE_DIR"] = str(Path(scratch) / "numba-cache")
        for phase in ([] if args.quick else ["cold"]) + ["warm"]:
            for command in COMMANDS:
                seconds, last = timed(command, env, Path(scratch) / f"{phase}-run")
                rows[command][f"{phase}_s"] = round(seconds, 1)
                if command != "tumble run":
                    rows[command][f"{phase}_tests"] = counts(last)
                print(f"{phase:5} {command:18} {seconds:7.1f} s  {last}", flush=True)
    record = {**provenance.stamp(), "quick": args.quick, "load_average_after": os.getloadavg()[0],
              "commands": rows}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "suite.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    lines = [f"# The README's commands, cold and warm — {record['date']}", "",
             f"Machine: {record['machine']}, vector width {record['vector_width']}; commit {record['commit']}. "
             "Cold: numba's cache empty (a fresh install's); warm: the same commands again on it. The install is not "
             "timed.", "", "| command | runs | cold | warm | tests |", "|---|---|---|---|---|"]
    for command, row in rows.items():
        tests = row.get("warm_tests", {})
        lines.append(f"| `{command}` | {row['runs']} | {row.get('cold_s', '—')} s | {row['warm_s']} s | "
                     f"{', '.join(f'{n} {kind}' for kind, n in tests.items()) or '—'} |")
    (args.out / "suite.md").write_text("\n".join(lines) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()

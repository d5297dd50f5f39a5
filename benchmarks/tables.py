"""The tables of figures the README and the docs show, rendered from the benchmarks' results files.

Every figure the README, ``docs/index.md``, ``docs/performance.md`` and ``docs/benchmark-results.md`` give comes from
one place: a ``benchmarks/results/*.json`` file, as its benchmark last wrote it. Each table sits in its page between
two marker comments::

    <!-- tables:begin NAME -->
    ...
    <!-- tables:end NAME -->

and says under it the machine, vector width, date and commit of every file it read. ::

    python benchmarks/tables.py           # rewrite every table from the results files
    python benchmarks/tables.py --check   # exit 1 naming each table that differs from its results (none rewritten)

It reads JSON and writes Markdown only (no tumble, no numba): ``tests/test_tables.py`` runs the check.
"""

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
#: The pages with tables, and how a link from each reaches ``benchmarks/results/``.
PAGES = {"README.md": "benchmarks/results/", "docs/index.md": "../benchmarks/results/",
         "docs/performance.md": "../benchmarks/results/", "docs/benchmark-results.md": "../benchmarks/results/",
         "docs/physics.md": "../benchmarks/results/", "docs/studies.md": "../benchmarks/results/",
         "docs/howto/own-system.md": "../../benchmarks/results/",
         "docs/explanation/chaos-maps.md": "../../benchmarks/results/"}
#: Doubles a SIMD register holds, by vector width.
DOUBLES = {"AVX-512": 8, "AVX2": 4}
_MARKED = re.compile(r"(<!-- tables:begin (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- tables:end (?P=name) -->)", re.S)


def results(name):
    """The parsed ``benchmarks/results/<name>.json``."""
    return json.loads((RESULTS / f"{name}.json").read_text(encoding="utf-8"))


def machine_line(machine):
    """A results file's ``machine``, a line or a record, as one line."""
    if isinstance(machine, str):
        return machine
    processor = machine.get("processor") or machine.get("platform", "unknown processor")
    cores = machine.get("cores") or machine.get("cpu_count")
    return f"{processor}, {cores} cores" + (f", numba {machine['numba']}" if "numba" in machine else "")


def sources(names, link):
    """Under a table: the results files ``names`` it reads, and the machine, vector width and date of their runs (one
    sentence for the files alike) with each file's commit."""
    groups = {}
    for name in dict.fromkeys(names):
        data = results(name)
        width = data["vector_width"]
        doubles = f", {DOUBLES[width]} doubles a register" if width in DOUBLES else ""
        key = f"{machine_line(data['machine'])} (vector width {width}{doubles}), {data['date'][:10]}"
        groups.setdefault(key, []).append(f"[`{name}.json`]({link}{name}.md), commit `{data['commit']}`")
    return " ".join(f"{'Measured on' if i == 0 else 'On'} {key}: {'; '.join(files)}."
                    for i, (key, files) in enumerate(groups.items()))


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]


def num(x, unit=""):
    """Three significant figures; thousands in full."""
    if x is None:
        return "—"
    text = f"{x:,.0f}" if abs(x) >= 1000 else f"{x:.3g}"
    return text + unit


def seconds(x):
    if x is None:
        return "—"
    return num(x * 1e6, " µs") if x < 1e-3 else num(x * 1e3, " ms") if x < 1 else num(x, " s")


def rate(x):
    return "—" if x is None else f"{x:.3g}".replace("e+0", "e").replace("e+", "e")


def fastest_tumble(chaos_results):
    """The fastest tumble row of ``chaos.json`` that met equal accuracy."""
    return min((r for r in chaos_results["rows"] if r["tool"] == "tumble" and r.get("equal_accuracy")),
               key=lambda r: r["seconds"])


# --- the tables --------------------------------------------------------------------------------------------------

def headline(link):
    """The README's and the docs home page's: tumble against a peer measured in the same run, one row a claim, from
    the benchmarks rerun on the current code (the chaos map against its peers, a run of hours, is in performance.md's
    chaos table with its own date and machine)."""
    s, w, e, u = (results(n) for n in ("sections", "work_precision", "eccentric_orbit", "user_systems"))
    at = w["speedups"]["1e-10"]
    tte, spins, best = at["time_to_error_s"], w["settings"]["samples"], at["comparison"]["best"]
    ecc = next(r for r in e["comparison_max"] if r["error"] == 1e-8)
    prop = {r["path"]: r for r in u["rows"] if r["call"] == "propagate"}
    meg = {r["path"]: r for r in u["rows"] if r["call"] == "megno"}
    own, own_meg = prop["System, vectorised blocks"], meg["System with its Jacobian, vectorised blocks"]
    rows = [
        (f"Poincaré sections: {s['releases']:,} heavy-top orbits to T = {s['t_end_s']:,.0f} s, rtol {s['rtol']:g}",
         f"`tumble.section` {seconds(s['tumble_s'])}",
         f"SciPy `solve_ivp(DOP853, events)` {seconds(s['scipy_s_scaled'])}",
         f"{num(s['speedup'])}× faster", "sections"),
        (f"{spins:,} spins to an error of 1e-10, closed form", f"`method=\"exact\"` {seconds(tte['exact'])}",
         f"SciPy DOP853 {seconds(tte['scipy_DOP853'])}", f"{num(at['speedup']['exact'])}× faster", "work_precision"),
        (f"{spins:,} spins to an error of 1e-10, fixed step", f"{best} {seconds(tte[best])}",
         f"SciPy DOP853 {seconds(tte['scipy_DOP853'])}", f"{num(at['comparison']['best_time_x_dop853'])}× faster",
         "work_precision"),
        (f"{spins:,} spins to an error of 1e-10, error-controlled", f"dop853 {seconds(tte['dop853'])}",
         f"SciPy DOP853 {seconds(tte['scipy_DOP853'])}", f"{num(at['speedup']['dop853'])}× faster", "work_precision"),
        (f"Eccentric spin-orbit ensemble (e = {e['scene'].get('eccentricity', 0.9):g}), max error 1e-8",
         f"dop853 {seconds(ecc['dop853_s'])}", f"fixed-step {ecc['best_fixed']} {seconds(ecc['best_fixed_s'])}",
         f"{num(ecc['ratio'])}× faster", "eccentric_orbit"),
        (f"Your own `System` (a heavy top): `propagate`, {own['samples']:,} samples", seconds(own["seconds"]),
         f"built-in model {seconds(prop['built-in HeavyTop']['seconds'])}", f"{num(own['vs_built_in'])}× its time",
         "user_systems"),
        (f"Your own `System` with its Jacobian: `megno`, {own_meg['samples']:,} samples", seconds(own_meg["seconds"]),
         f"built-in model {seconds(meg['built-in HeavyTop']['seconds'])}", f"{num(own_meg['vs_built_in'])}× its time",
         "user_systems"),
    ]
    body = table(("task", "tumble", "peer, same run", "ratio"), [r[:4] for r in rows])
    return body + ["", sources([r[4] for r in rows], link)]


def results_index(link):
    """``docs/benchmark-results.md``'s: every results file and what it was measured on."""
    rows = []
    for path in sorted(RESULTS.glob("*.json")):
        data = results(path.stem)
        report = f"[{path.stem}]({link}{path.stem}.md)" if path.with_suffix(".md").exists() else path.stem
        rows.append((report, machine_line(data["machine"]), data["vector_width"], data["date"][:10],
                     f"`{data['commit']}`"))
    return table(("results", "machine", "vector width", "date", "commit"), rows)


def engine(link):
    d = results("engine")
    rows = [(f"`{r['method']}`", rate(r["fast"]), rate(r.get("naive")),
             f"{r['speedup']:.1f}×" if r.get("speedup") else "—") for r in d["throughput"]]
    return table(("method", "sample-steps/s", "one sample at a time, sample-steps/s", "speed-up"), rows) + [
        "", sources(["engine"], link)]


def roofline(link):
    d = results("engine")
    rows = [(f"`{r['method']}`", r["multiplies"], rate(r["rate"]), rate(r["bound"]), f"{100 * r['fraction']:.0f} %")
            for r in d["roofline"]]
    peak = d["roofline"][0]["peak"]
    return table(("method", "multiplies + FMAs per sample-step", "sample-steps/s", "bound", "fraction of the bound"),
                 rows) + ["", f"The bound: {rate(peak)} multiply-adds/s measured on all cores, divided by a step's "
                          "multiplies and multiply-adds. " + sources(["engine"], link)]


def torque_paths(link):
    d = results("engine")
    by = {(r["method"], r["torque"]): r["rate"] for r in d["torque_paths"]}
    rows = [(f"`{m}`", rate(by[m, "profile"]), rate(by[m, "function"]), f"{by[m, 'function'] / by[m, 'profile']:.2f}×")
            for m in dict.fromkeys(r["method"] for r in d["torque_paths"])]
    return table(("method", "built-in profile, sample-steps/s", "torque function, sample-steps/s",
                  "function / profile"), rows) + ["", sources(["engine"], link)]


def overhead(link):
    d = results("engine")
    rows = [(f"`{r['call']}`", seconds(r["seconds"])) for r in d["overhead"]]
    memory = d["memory"]
    rows += [(f"`tumble.measure`, warm growth scene, {r['path']}", seconds(r["seconds"])) for r in d["warm_scene"]]
    rows.append((f"peak memory of a {memory['samples']:,}-sample growth measurement ({memory['n_steps']:,} rk4 steps)",
                 f"{memory['peak_mib']:.0f} MiB"))
    return table(("one call, one sample and one step unless said", "median"), rows) + ["", sources(["engine"], link)]


def work_precision(link):
    d = results("work_precision")
    targets = d["targets"]

    def verdict(ratio, key, c):
        said = c["verdicts"].get(key, "no target")
        if ratio is None:
            return said if said.startswith("met") else "—"
        return num(ratio, "×") + ("" if said == "no target" else f" (≥ {targets[key][0]:g}×: {said})")

    rows = []
    for label, part in d["speedups"].items():
        c, t = part["comparison"], part["time_to_error_s"]
        best = f"{c['best']}, {seconds(c['best_time'])}" if c["best"] else "not reached"
        rows.append((label, seconds(c["dop853"]) if c["dop853"] else "not reached",
                     seconds(c["heyoka"]) if c["heyoka"] else "not reached", best,
                     verdict(c["best_time_x_dop853"], "best_tumble_x_dop853", c),
                     verdict(c["best_time_x_heyoka"], "best_tumble_x_heyoka", c),
                     seconds(t["dop853"]) if t.get("dop853") else "not reached", seconds(c["exact"]),
                     verdict(c["exact_x_dop853"], "exact_x_dop853", c),
                     verdict(c["fastest_x_heyoka"], "fastest_tumble_x_heyoka", c)))
    s = d["settings"]
    return table(("error", "SciPy DOP853", "heyoka", "best fixed-step tumble", "vs DOP853", "vs heyoka",
                  "tumble dop853", "closed form", "closed form vs DOP853", "tumble's fastest vs heyoka"), rows) + [
        "", f"{s['samples']:,} spins tilted {s['amplitude']:g} rad from the intermediate axis of I = "
            f"({', '.join(f'{x:g}' for x in s['body'])}), to t = {s['t_end']:g} s; medians of {s['repeats']} passes. " +
            sources(["work_precision"], link)]


def closed_form(link):
    d = results("closed_form")
    rows = []
    for regime in d["one_time"]:
        one, grid = d["one_time"][regime], d["regimes"][regime]
        rows.append((f"near the {regime}", rate(one["new_1"]), rate(one["new_2"]),
                     f"{one['speedup_1']:.1f}× / {one['speedup_2']:.1f}×", rate(grid["new_2"])))
    return table(("spins", "one time, 1 thread", "one time, 2 threads", "over the time-grid path (1 / 2 threads)",
                  f"time grid of {d['times']}, 2 threads"), rows) + [
        "", "Evaluations per second. " + sources(["closed_form"], link)]


def stress(link):
    d = results("stress")

    def span(lo, hi):
        return f"{lo:.3g}" if f"{lo:.3g}" == f"{hi:.3g}" else f"{lo:.3g} … {hi:.3g}"

    rows = [(f"`{m}`", f"{s['l2_max']:.1e}", f"{s['energy_max']:.1e}", span(s["edge_min"], s["edge_max"]),
             span(s["edge_theory_min"], s["edge_theory_max"]),
             f"{s['accurate_up_to']:.3g}" if s.get("accurate_up_to") else "< 0.05")
            for m, s in d["summary"].items()]
    st = d["settings"]
    return table(("method", "max \\|ΔL²\\|/L²", "max \\|ΔE\\|/E", "largest stable hΩ", "its one-step map's theory",
                  "precession error ≤ 1e-3 up to hΩ"), rows) + [
        "", f"Drift over {rate(st['long_steps'])} steps of dt = {st['long_dt']:g} s. " + sources(["stress"], link)]


def stress_limits(link):
    d = results("stress")

    def values(xs):
        return ", ".join(f"{x:.0e}" for x in xs) if xs else "none"

    rows = [(f"`{m}`", f"{s['scale_max_diff']:.1e}", "yes" if s.get("scale_power_of_two_identical") else "no",
             f"{s['first_flip_trusted_down_to']:.0e}", f"{s['spacing_trusted_down_to']:.0e}",
             values(s["beyond_flagged"]), values(s["beyond_silent"]))
            for m, s in d["summary"].items()]
    return table(("method", "spin rates rescaled: max rel. difference", "powers of two bit-identical",
                  "first flip timed down to tilt", "flip spacing trusted down to tilt", "\\|ω\\| flagged",
                  "\\|ω\\| silently wrong"), rows) + ["", sources(["stress"], link)]


def _leading_parts(text, n):
    """The first ``n`` comma-separated parts of ``text`` (commas inside parentheses do not separate)."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(text):
        depth += (char == "(") - (char == ")")
        if char == "," and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    parts.append(text[start:].strip())
    return ", ".join(parts[:n])


def chaos(link):
    d = results("chaos")
    fastest = fastest_tumble(d)
    rows = []
    for r in d["rows"]:
        agreement = f"{100 * r['agreement']:.2f} %" if r.get("agreement") is not None else "—"
        tool = _leading_parts(r["settings"].split(";")[0], 3).replace("(", " (")  # a call's name and its arguments
        rows.append((tool, seconds(r["seconds"]), seconds(r["setup_seconds"]),
                     r["measured"],
                     agreement, f"{100 * r['lyapunov_error']:.1f} %",
                     "" if r["tool"] == "tumble" else f"{num(r['seconds'] / fastest['seconds'])}×"))
    ref = d["reference"]
    return table(("tool", "map", "compile or set-up", "measured", "same class as reference", "λ1 mean error",
                  "slower than tumble"), rows) + [
        "", f"{d['grid']} × {d['grid']} releases to T = {d['horizon']:g} s; the reference "
            f"({_leading_parts(ref['settings'].removeprefix('reference: '), 2)}) took {seconds(ref['seconds'])}, "
            f"λ1 mean {ref['lyapunov_mean']:.4f} 1/s. "
            + sources(["chaos"], link)]


def first_call(link):
    d = results("first_call")
    targets = d["targets_seconds"]
    rows = [(r["name"], seconds(r["empty_s"]), seconds(r["warm_s"]),
             " / ".join(f"{t:.3g} s" for t in targets[r["name"]]) if r["name"] in targets else "")
            for r in d["rows"]]
    return table(("first call", f"empty numba cache (median of {d['repeats_empty']})",
                  f"warm cache, new process (median of {d['repeats_warm']})", "target (empty / warm)"), rows) + [
        "", sources(["first_call"], link)]


def suite(link):
    """The README's Quickstart: what each of its commands runs, and what it costs on an empty and a warm cache."""
    d = results("suite")

    def tests(row):
        found = row.get("warm_tests") or row.get("cold_tests") or {}
        return ", ".join(f"{n:,} {kind}" for kind, n in found.items() if kind != "deselected")

    rows = [(f"`{command}`", row["runs"] + (f" ({tests(row)})" if tests(row) else ""), seconds(row.get("cold_s")),
             seconds(row["warm_s"])) for command, row in d["commands"].items()]
    # and the Python API's first calls that issue 58's targets hold (benchmarks/first_call.py), each in a new process
    calls = results("first_call")
    calls_named = {"integrate rk4": "`tumble.integrate` (rk4)", "exact.omega": "`tumble.exact.omega`",
                   "measure": "`tumble.measure`", "integrate System": "`tumble.integrate` of your own `System`"}
    rows += [(calls_named[r["name"]], "its first call in a new process", seconds(r["empty_s"]), seconds(r["warm_s"]))
             for r in calls["rows"] if r["name"] in calls_named]
    return table(("command", "runs", "first time (empty numba cache)", "again (warm cache)"), rows) + [
        "", sources(["suite", "first_call"], link)]


def latency(link):
    d = results("latency")
    targets = d["targets_seconds"]
    rows = [(k, seconds(v["median"]), f"{targets[k]:g} s" if k in targets else "")
            for k, v in d["shell_seconds"].items()]
    rows += [(k if "in process" in k else f"{k}, in process", seconds(v), "")
             for k, v in d["in_process_seconds"].items()]
    return table(("what a user waits for", f"median of {d['repeats']}", "target"), rows) + [
        "", sources(["latency"], link)]


def attitude(link):
    """``docs/physics.md``'s: ``tumble.integrate`` without and with the attitude, per method."""
    d = results("attitude")
    m = d["meta"]
    rows = [(f"`{r['method']}`", seconds(r["plain_s"]), r["attitude_calls_when_not_asked"], seconds(r["attitude_s"]),
             f"{r['attitude_s'] / r['plain_s']:.3g}×") for r in d["rows"]]
    steps = round(m["t_end"] / m["dt"])
    return table(("method", "attitude=False", "attitude code called when not asked", "attitude=True",
                  "with / without"), rows) + [
        "", f"`tumble.integrate` on {m['samples']:,} spins, {steps:,} steps of dt = {m['dt']:g} s, every "
            f"{m['save_every']}th stored; medians of {m['repeats']}, first calls apart. " + sources(["attitude"], link)]


def models(link):
    """``docs/physics.md``'s: each model's kernels against the free body's own rk4 driver, per state component."""
    d = results("models")
    rows = [(r["kernel"], f"`{r['method']}`", r["components"], rate(r["sample_steps"]), rate(r["component_steps"]),
             f"{r['ratio']:.2f}×") for r in d["rows"]]
    return table(("kernel", "method", "state components", "sample-steps/s", "component-steps/s",
                  "component-steps against the free body's rk4"), rows) + [
        "", f"{d['samples']:,} samples × {d['steps']} steps, {d['threads']} threads, medians of {d['repeats']}. "
            + sources(["models"], link)]


def scans(link):
    """``docs/studies.md``'s: a bundled map through ``tumble.run_study`` in one process, no files written."""
    s, m = results("scan"), results("model_scan")
    big = s["big"]
    rows = [(f"`stability_map`: {s['scenes']:,} closed-form scenes of {s['samples']} samples, warm",
             seconds(s["study"])),
            ("… first run in the process", seconds(s["study_first"])),
            (f"… planning the {s['scenes']:,} scenes", seconds(s["planning"])),
            ("… measuring them batched", seconds(s["batched"])),
            ("… measuring them one scene a call", seconds(s["one_by_one"])),
            ("… assembling the dataset", seconds(s["assemble"])),
            (f"the same map at {big['scenes']:,} scenes, in a fresh process with cached kernels", seconds(big["seconds"])),
            ("… its peak resident memory", f"{big['peak_mib']:.0f} MiB"),
            (f"a gyrostat map: {m['scenes']:,} rk4 scenes of {m['samples']} samples, warm", seconds(m["study"])),
            ("… first run in the process", seconds(m["first"])),
            (f"… planning the {m['scenes']:,} scenes", seconds(m["planning"])),
            ("… measuring them", seconds(m["measuring"]))]
    return table(("scan", "median"), rows) + ["", sources(["scan", "model_scan"], link)]


def scale_out(link):
    """``docs/studies.md``'s: one scan in-process and on a dask LocalCluster."""
    d = results("scale_out")
    one = d["medians_s"]["LocalCluster, 1 worker"]
    client = {k: sorted(v)[len(v) // 2] for k, v in d["client_cpu_s"].items()}
    rows = [(k, seconds(v), f"{one / v:.2f}×", seconds(client[k]) if k in client else "(all of it)")
            for k, v in d["medians_s"].items()]
    rows.append(("resuming the finished scan (read its chunks, assemble, write)", seconds(d["resume_rerun_s"]), "", ""))
    return table(("how", "wall", "against 1 worker", "CPU of the client process"), rows) + [
        "", f"{d['scenes']} rk4 scenes of {d['samples']:,} samples, {d['chunk_scenes']} scenes a chunk, medians of "
            "interleaved runs. " + sources(["scale_out"], link)]


def user_systems(link):
    """``docs/howto/own-system.md``'s: a heavy top written as a ``System`` against the built-in model."""
    d = results("user_systems")
    rows = [(f"`{r['call']}`", r["path"], f"{r['samples']:,} × {r['steps']:,}", seconds(r["seconds"]),
             f"{r['vs_built_in']:.2f}×") for r in d["rows"]]
    first = d["first_call"]
    rows += [("first `propagate` in a new process, import included", "empty numba cache", "",
              seconds(first["empty_cache_s"]), ""),
             ("first `propagate` in a new process, import included", "the cache the first process filled", "",
              seconds(first["warm_cache_s"]), "")]
    return table(("call", "path", "samples × steps", "time", "built-in's time ×"), rows) + [
        "", sources(["user_systems"], link)]


TABLES = {"headline": headline, "results": results_index, "engine": engine, "roofline": roofline,
          "torque-paths": torque_paths, "overhead": overhead, "work-precision": work_precision,
          "closed-form": closed_form, "stress": stress, "stress-limits": stress_limits, "chaos": chaos,
          "first-call": first_call, "latency": latency, "attitude": attitude, "models": models, "scans": scans,
          "scale-out": scale_out, "user-systems": user_systems, "suite": suite}


def render(text, link):
    """``text`` with every marked table rendered afresh; ``(text, [names of tables that changed])``."""
    changed = []

    def fresh(match):
        name = match["name"]
        if name not in TABLES:
            raise KeyError(f"no table named {name!r} (known: {', '.join(TABLES)})")
        body = "\n" + "\n".join(TABLES[name](link)) + "\n\n"
        if body != match["body"]:
            changed.append(name)
        return match[1] + body + match[4]

    return _MARKED.sub(fresh, text), changed


def stale():
    """``["<page>: <table>", ...]`` for every table whose page differs from what the results files give."""
    found = []
    for page, link in PAGES.items():
        _, changed = render((ROOT / page).read_text(encoding="utf-8"), link)
        found += [f"{page}: {name}" for name in changed]
    return found


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="rewrite nothing; exit 1 naming each stale table")
    args = parser.parse_args(argv)
    if args.check:
        found = stale()
        for line in found:
            print(f"stale table: {line} (python benchmarks/tables.py rewrites it)", file=sys.stderr)
        return 1 if found else 0
    for page, link in PAGES.items():
        path = ROOT / page
        text, changed = render(path.read_text(encoding="utf-8"), link)
        if changed:
            path.write_text(text, encoding="utf-8")
            print(f"{page}: rewrote {', '.join(changed)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Sphinx extension of tumble's site: reference pages generated from the code, and the docstring check.

Directives (used from the Markdown pages under ``docs/reference/``), each writing Markdown that MyST parses:

``tumble-api``
    The Python API, grouped by task (:data:`API_GROUPS`): every name of ``tumble.__all__``, a function or class by
    autodoc, a module (``tumble.exact``, ...) with the members of its ``__all__`` but the internals
    (:data:`INTERNAL`).
``tumble-study-keys``
    Every field of a study with its default, units, allowed values and doc, and every ``[scan]`` key with the field it
    replaces: all from the one description of a study, :data:`tumble.pipeline.schema.FIELDS` (which also writes
    ``studies/defaults.toml``), never from a copy.
``tumble-netcdf``
    The variables (dimensions, units, long name) and global attributes of a result file written by ``tumble run``
    (the argument: a netCDF file, relative to the page).
``tumble-gallery``
    The figures of the bundled studies (the argument: ``studies/gallery/``, relative to the page), each under the
    command that made it.

Links: a Markdown link to a file of the repository outside ``docs/`` becomes its text (:class:`RepositoryLinks`);
a Python reference may name a public module by its short path or where it lives (``tumble.io`` or
``tumble.output.io``: :func:`_public_alias`).

At ``builder-inited`` every public name (``tumble.__all__`` and the ``__all__`` of the public modules, with the
public methods of public classes) is checked for a docstring; each one missing is a warning, so that the build
with ``-W`` fails and names it.
"""

import importlib.util
import inspect
import re
import shutil
import tomllib
from pathlib import Path

from docutils import nodes
from sphinx import addnodes
from sphinx.transforms.post_transforms import SphinxPostTransform
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective
from docutils.transforms import Transform

logger = logging.getLogger(__name__)

def study_keys(path):
    """``{(table, key): comment lines}`` for every ``key = value`` line of the defaults file at ``path``
    (``table`` "" for the top level): the comment block right above the key. A table's first comment block that
    stands alone (followed by a blank line, as ``[scan]``'s, a table without keys) is the table's, under key ""."""
    comments, comment, table = {}, [], ""
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        stripped = line.strip()
        if stripped.startswith("#"):
            comment.append(stripped[1:].removeprefix(" "))
            continue
        if stripped.startswith("["):
            table = stripped.strip("[]")
        elif stripped:
            comments[(table, stripped.split("=")[0].strip())] = comment
        elif comment:  # a comment block that ends in a blank line: the table's own (the first such)
            comments.setdefault((table, ""), comment)
        comment = []
    return comments


def _cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def _code(value):
    return f"`{value!r}`" if isinstance(value, str) else f"`{value}`".replace("True", "true").replace("False", "false")


def study_reference(path=None):
    """Markdown: one table per study table, from the description of a study (:data:`tumble.pipeline.schema.FIELDS`).
    ``path``: the defaults file, which must be that description's rendering (a warning says when it is not)."""
    from tumble.pipeline import schema

    if path is not None and Path(path).read_text(encoding="utf-8") != schema.defaults_toml():
        logger.warning(f"{path} is not the rendering of tumble/pipeline/schema.py: run python -m tumble.pipeline.schema")
    lines = []
    for table in ("", *schema.TABLES):
        lines += [f"## `[{table}]`" if table else "## Top level", ""]
        if table == "scan":
            lines += ["```text", *schema.SCAN_DOC.splitlines(), "```", ""]
            lines += ["| key | replaces | units |", "|---|---|---|"]
            lines += [f"| `scan.{f.key}` | `{f.replaces}` | {_cell(f.units)} |"
                      for f in schema.table_fields("scan")]
            lines.append("")
            continue
        lines += ["| key | default | units | allowed values | meaning |", "|---|---|---|---|---|"]
        for f in schema.table_fields(table):
            shown = ", ".join(_code(v) for v in f.choices) if f.choices else ""
            text = " ".join(f.doc.splitlines())
            lines.append(f"| `{f.path}` | {_cell(_code(f.default))} | {_cell(f.units)} | {_cell(shown)} | "
                         f"{_cell(text)} |")
        lines.append("")
    return "\n".join(lines)


def netcdf_reference(path):
    """Markdown: the coordinates, variables and global attributes of the netCDF file at ``path``."""
    import xarray as xr

    with xr.open_dataset(path) as ds:
        lines = ["| variable | dimensions | units | long name |", "|---|---|---|---|"]
        for kind, names in (("coordinate", ds.coords), ("data", ds.data_vars)):
            for name in names:
                var = ds[name]
                dims = ", ".join(var.dims) if var.dims else "(scalar)"
                label = f"`{name}`" + (" (coordinate)" if kind == "coordinate" else "")
                lines.append(f"| {label} | {_cell(dims)} | {_cell(var.attrs.get('units', ''))} | "
                             f"{_cell(var.attrs.get('long_name', ''))} |")
        lines += ["", "| global attribute | value in this file |", "|---|---|"]
        for name, value in ds.attrs.items():
            text = str(value)
            lines.append(f"| `{name}` | {_cell(text if len(text) <= 100 else text[:100] + ' ...')} |")
    return "\n".join(lines)


def figure_caption(name):
    """What the figure ``name`` shows: the first paragraph of the docstring of the function that draws it
    (``tumble.output.figures.<name>``), in MyST (its reStructuredText roles and literals rewritten); "" if none."""
    from tumble.output import figures

    doc = inspect.getdoc(getattr(figures, name, None)) or ""
    text = " ".join(doc.split("\n\n")[0].split())
    text = re.sub(r":(\w+):`", r"{\1}`", text)  # :func:`x` -> {func}`x`
    return text.replace("``", "`")


def gallery(folder, page_dir):
    """Markdown: every figure in ``folder`` (``studies/gallery/``) as a thumbnail in one grid, opening the figure at
    full size, captioned with what it shows (:func:`figure_caption`), the bundled study whose name starts its file
    name (linked to the study file on the bundled-studies page) and the command that draws it again; paths relative
    to ``page_dir``."""
    import os

    from tumble import registry
    from tumble.pipeline.config import bundled_studies

    if not Path(folder).is_dir():
        logger.warning(f"tumble-gallery: no folder {folder}")
        return ""
    studies = bundled_studies()
    lines = ["::::{container} tumble-gallery", ""]
    for study, title in studies.items():
        figures = sorted(f for f in Path(folder).iterdir() if f.stem.startswith(study + "_")
                         and not any(f.stem.startswith(other + "_") and len(other) > len(study) for other in studies))
        for figure in figures:
            name = figure.stem.removeprefix(study + "_")
            if name not in registry.FIGURES:
                logger.warning(f"gallery figure {figure.name} in {folder}: {name!r} is no figure of registry.FIGURES")
            shows = figure_caption(name)
            lines += [f":::{{figure}} {Path(os.path.relpath(figure, page_dir)).as_posix()}",
                      f":alt: {title}: the {name} figure", ":width: 100%", "",
                      f"**{title}** — `{name}`{': ' + shows if shows else ''}", "",
                      f"Study: {{ref}}`studies/{study}.toml <study-{study}>`; drawn by `tumble run {study}`.", ":::", ""]
    lines += ["::::", ""]
    unmatched = [f.name for f in Path(folder).iterdir() if not any(f.stem.startswith(s + "_") for s in studies)]
    for name in unmatched:
        logger.warning(f"gallery figure {name} in {folder} names no bundled study")
    return "\n".join(lines)


def bundled_studies_page(page_dir):
    """Markdown: the documented defaults and every bundled study file, each under the label ``study-<name>`` that
    links to ``studies/<name>.toml`` lead to (:func:`repository_page`), with the command that runs it."""
    import os

    from tumble.pipeline.config import DEFAULTS_PATH, bundled_studies

    def source(path):
        return Path(os.path.relpath(path, page_dir)).as_posix()

    lines = ["(study-defaults)=", "## `defaults.toml`", "",
             "Every key and its default, with the comment that documents it (the [study-file reference](study-file.md) "
             "is generated from it).", "", f"```{{literalinclude}} {source(DEFAULTS_PATH)}", ":language: toml", "```", ""]
    for name, title in bundled_studies().items():
        path = DEFAULTS_PATH.parent / f"{name}.toml"
        lines += [f"(study-{name})=", f"## `{name}`", "", f"{title}: `tumble run {name}`.", "",
                  f"```{{literalinclude}} {source(path)}", ":language: toml", "```", ""]
    return "\n".join(lines)


def benchmark_results_page(results, page_dir):
    """Markdown: every ``benchmarks/results/*.md`` (``results``), each under the label ``bench-<name>`` that links to
    the file lead to (:func:`repository_page`), its headings one level down."""
    import os

    lines = []
    for path in sorted(Path(results).glob("*.md")):
        lines += [f"(bench-{path.stem})=", f"```{{include}} {Path(os.path.relpath(path, page_dir)).as_posix()}",
                  ":heading-offset: 1", "```", ""]
    return "\n".join(lines)


def citation(path):
    """``{field: value}`` of the top-level scalar fields of a ``CITATION.cff`` (``title``, ``version``, ...) and
    ``authors``: the list of its authors' names (a YAML reader for the few lines tumble's file has)."""
    fields, authors = {}, []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if match := re.fullmatch(r"  - name: (.+)", line):
            authors.append(match.group(1).strip().strip('"'))
        elif match := re.fullmatch(r"([a-z-]+): (.+)", line):
            fields[match.group(1)] = match.group(2).strip().strip('"')
    return {**fields, "authors": authors}


def citation_page(path):
    """Markdown: a BibTeX entry for tumble from its ``CITATION.cff`` at ``path``, then the file itself."""
    import tumble

    cff = citation(path)
    if cff.get("version") != tumble.__version__:
        logger.warning(f"{path}: version {cff.get('version')!r} is not tumble's {tumble.__version__!r}")
    authors = " and ".join(f"{{{name}}}" for name in cff["authors"])
    bibtex = ["@software{tumble,", f"  title   = {{{cff['title']}}},", f"  author  = {{{authors}}},",
              f"  version = {{{cff['version']}}},", f"  license = {{{cff['license']}}},", "}"]
    return "\n".join(["```bibtex", *bibtex, "```", "", "```{literalinclude} /../" + Path(path).name, ":language: yaml",
                      "```"])  # "/": from the site's source folder, whose parent holds the file


#: What each extra of ``pyproject.toml`` is for (its packages are read from the file); an extra missing here fails
#: the build.
EXTRAS = {
    "test": "the test suite (`python -m pytest`): pytest and its two workers, hypothesis, mpmath as the exact "
            "solution's reference, numba-cuda for its simulator, and the `docs` and `engines` extras",
    "docs": "this site: `sphinx-build -W --keep-going -b html docs docs/_build/html`, with its MathJax carried locally",
    "engines": "real physics engines' trajectories through `tumble check` (`benchmarks/engines.py`)",
    "distributed": "`tumble run --scheduler local` or `tcp://HOST:PORT`: the scenes on dask.distributed",
    "gpu": "`device=\"cuda\"` and `tumble run --device cuda` on an NVIDIA GPU",
    "bench": "heyoka, the Taylor-integrator peer of the work-precision benchmark and study (optional there)",
}


def extras_table(pyproject):
    """Markdown: a table of the optional dependencies of ``pyproject`` (``pyproject.toml``): extra, packages, use."""
    extras = tomllib.loads(Path(pyproject).read_text(encoding="utf-8"))["project"]["optional-dependencies"]
    lines = ["| extra | brings | for |", "|---|---|---|"]
    for name, requirements in extras.items():
        if name not in EXTRAS:
            logger.warning(f"extra {name!r} of {pyproject} is not described: add it to EXTRAS in {__file__}")
        packages = ", ".join(f"`{r}`" for r in requirements)
        lines.append(f"| `{name}` | {_cell(packages)} | {_cell(EXTRAS.get(name, ''))} |")
    return "\n".join(lines)


def _public_modules():
    """``{public name: module}`` of the modules ``tumble.__all__`` exports (``tumble.exact`` is
    ``tumble.physics.exact``)."""
    import tumble

    return {name: getattr(tumble, name) for name in tumble.__all__ if inspect.ismodule(getattr(tumble, name))}


#: Where the API's pages are generated, relative to the site's source folder (git-ignored): one page per public
#: function and class, one per public module.
API_FOLDER = "reference/api"

_CONSTANT = re.compile(r"[A-Z][A-Z0-9_]*")


#: The API index's groups, by task: (title, what the group is for, public names of ``tumble.__all__``: functions and
#: classes, and modules whose public members follow in a subsection each). Every public name of ``tumble.__all__`` is
#: in one group; one that is not fails the build (:func:`api_groups`).
API_GROUPS = (
    ("Bodies and models", "What spins: a rigid body from its moments or its shape, the models beyond the free body, a "
     "user's own system, and the quaternions of an attitude.", ("Body", "System", "shapes", "models", "rotations")),
    ("Integrate", "Step an ensemble of initial states, or evaluate it in closed form, and draw the ensemble.",
     ("integrate", "propagate", "run_ensemble", "section", "sampling")),
    ("Measure and scan", "Growth rates and frequencies of perturbed spins against linear theory: one scene, a scan of "
     "scenes, the laws fitted over a scan, and one spin's orientation for the figures.",
     ("measure", "scan", "inertia_triangle", "regress_scan", "flip_time_law", "attitude_trace")),
    ("Exact solution", "The torque-free motion in closed form (Jacobi elliptic functions), and the linear theory of "
     "steady spins that the measurements are compared with.", ("exact", "theory")),
    ("Chaos", "Indicators of chaos for any system: Lyapunov spectra, MEGNO and GALI.", ("lyapunov", "megno", "gali")),
    ("Check", "Another simulator's trajectory against the exact solution.", ("check",)),
    ("Studies", "A study file (or mapping) run from end to end, as `tumble run` runs it.", ("run_study",)),
    ("I/O", "Result files: written atomically with their provenance, read back checked.", ("io",)),
)

#: Members of the public modules' ``__all__`` that are internals, left out of the API index and without pages: the
#: closed form's device and row-level entry points (below the checks of :func:`tumble.exact.omega`), the sampling's
#: unchecked draw, the helpers of :func:`tumble.io.write_dataset`, and the plain-array record the kernels read.
INTERNAL = re.compile(r"tumble\.(exact\.(\w+_on_device|attitude_rows)|sampling\.drawn_spins"
                      r"|io\.(assume_no_dask_arrays|netcdf_safe_attrs|stored_form|provenance)|models\.Transverse)")


def api_groups():
    """``[(title, what it is for, [(public module name or None, [public dotted names])])]``, in the order of
    :data:`API_GROUPS`: per group, its functions and classes of ``tumble.__all__`` (module None), then each of its
    public modules (``tumble.exact``, ...) with the functions and classes of its ``__all__`` but :data:`INTERNAL`
    (its constants are documented on the module's page). A public name in no group is a warning (the build with
    ``-W`` fails)."""
    import tumble

    modules = _public_modules()
    public = [name for name in tumble.__all__ if not name.startswith("_")]
    grouped = {name for _, _, names in API_GROUPS for name in names}
    for name in public:
        if name not in grouped:
            logger.warning(f"tumble.{name} is in no group of the API index: add it to API_GROUPS in {__file__}")
    groups = []
    for title, intro, names in API_GROUPS:
        parts = []
        top = [f"tumble.{name}" for name in names if name in public and name not in modules]
        if top:
            parts.append((None, top))
        for name in names:
            if name in modules:
                members = [f"tumble.{name}.{member}" for member in getattr(modules[name], "__all__", ())
                           if not _CONSTANT.fullmatch(member) and not INTERNAL.fullmatch(f"tumble.{name}.{member}")]
                parts.append((f"tumble.{name}", members))
        groups.append((title, intro, parts))
    return groups


def api_sections():
    """``[(title, public module name or None, [public dotted names])]``: the parts of :func:`api_groups` in order, a
    group's functions and classes under the group's title, a module's members under the module's name."""
    return [(module or title, module, names) for title, _, parts in api_groups() for module, names in parts]


def public_objects():
    """``{public dotted name: object}`` of every function and class the API index lists (:func:`api_sections`)."""
    return {name: _resolve(name) for _, _, names in api_sections() for name in names}


def _resolve(dotted):
    """The object of a public dotted name (``tumble.exact.omega``)."""
    import tumble

    obj = tumble
    for part in dotted.split(".")[1:]:
        obj = getattr(obj, part)
    return obj


def _title(text):
    return f"{text}\n{'=' * len(text)}\n"


def _rst_to_myst(text):
    """reStructuredText's inline markup of a docstring as MyST: ``x`` -> `x`, :func:`x` -> {func}`x`."""
    return re.sub(r":(\w+):`", r"{\1}`", text).replace("``", "`")


def summary(obj):
    """The first sentence of ``obj``'s docstring (its first paragraph if no sentence ends sooner), as MyST."""
    text = " ".join((inspect.getdoc(obj) or "").split("\n\n")[0].split())
    end = re.search(r"[.:;](\s|$)(?=[A-Z(`*]|$)", text)
    return _rst_to_myst(text[:end.start() + 1] if end and end.start() < len(text) - 1 else text)


def _short_signature(obj, most=4):
    """``(body, w0, t_end, dt, ...)``: the names of the first ``most`` parameters of a callable, as a summary shows
    them (the page gives the rest); "" for no signature."""
    try:
        parameters = [p for p in inspect.signature(obj).parameters.values()
                      if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
    except (TypeError, ValueError):
        return ""
    names = [p.name for p in parameters[:most]] + (["..."] if len(parameters) > most else [])
    return f"({', '.join(names)})"


def summary_table(names, short=False):
    """Markdown: a table of the public ``names`` (dotted), each linked to its page with its signature, and the first
    sentence of its docstring (what autosummary writes, in a fraction of its time: it imports and analyses every
    name again). ``short``: show each by its last component (on its module's page)."""
    lines = ["| name | what it does |", "|---|---|"]
    for name in names:
        obj = _resolve(name)
        signature = _short_signature(obj)
        shown = name.rsplit(".", 1)[1] if short else name
        cell = f"{{py:obj}}`{shown} <{name}>`" + (f" `{signature}`" if signature else "")
        lines.append(f"| {_cell(cell)} | {_cell(summary(obj))} |")
    return "\n".join(lines)


def api_pages():
    """``{page file name: text}``: a reStructuredText page per public function and class, and a MyST page per public
    module (its docstring, a summary table of its members, its constants), each under the public name."""
    pages = {}
    for _, module, names in api_sections():
        for name in names:
            obj = _resolve(name)
            if inspect.isclass(obj):
                body = f".. autoclass:: {name}\n   :members:\n"
            else:
                body = f".. autofunction:: {name}\n"
            # A function's or class's page is in no toctree (":orphan:"): the summary tables link it. In the sidebar's
            # tree it would cost the theme's navigation, computed for every page, a second per ten pages.
            pages[f"{name}.rst"] = f":orphan:\n\n{_title(name)}\n{body}"
        if module is None:
            continue
        constants = [c for c in getattr(_resolve(module), "__all__", ()) if _CONSTANT.fullmatch(c)]
        text = [f"# `{module}`", "", "```{eval-rst}", f".. automodule:: {module}", "   :no-members:", "```", "",
                "## Functions and classes", "", summary_table(names, short=True), ""]
        if constants:
            text += ["## Constants", "", "```{eval-rst}",
                     *(f".. autodata:: {module}.{c}\n   :no-value:\n" for c in constants), "```", ""]
        pages[f"{module}.md"] = "\n".join(text)
    return pages


def write_api_pages(app):
    """Write the API's pages into ``API_FOLDER`` of the source folder (only those whose text changed, so that an
    incremental build stays incremental; stale ones removed). Only for a site that has the API index page."""
    source = Path(app.srcdir)
    if not (source / "reference" / "api.md").is_file():
        return
    folder = source / API_FOLDER
    folder.mkdir(parents=True, exist_ok=True)
    pages = api_pages()
    for stale in folder.iterdir():
        if stale.name not in pages:
            stale.unlink()
    for name, text in pages.items():
        path = folder / name
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")


def api_reference():
    """Markdown of the API's index page: per group of :data:`API_GROUPS` (by task) what it is for and a summary table
    of its functions and classes, then a subsection per public module of the group, whose heading links the module's
    page, with a summary table of its members; all linked to their pages (``write_api_pages``)."""
    folder = API_FOLDER.rsplit("/", 1)[-1]
    lines, modules = [], []
    for title, intro, parts in api_groups():
        lines += [f"## {title}", "", intro, ""]
        for module, names in parts:
            if module:
                modules.append(module)
                lines += [f"### [`{module}`]({folder}/{module}.md)", "", summary(_resolve(module)), ""]
            lines += [summary_table(names), ""]
    lines += ["```{toctree}", ":hidden:", "", *(f"{folder}/{module}" for module in modules), "```", ""]
    return "\n".join(lines)


def _public_module_aliases():
    """Make the public modules importable by their public names in the build (``import tumble.exact``), as autodoc and
    viewcode import a documented object's module: the pages name ``tumble.exact.omega``, and its
    ``[source]`` link leads to where it lives (``tumble/physics/exact.py``)."""
    import importlib
    import sys

    import tumble

    for short, module in tumble._ALIASES.items():  # noqa: SLF001 - the face's own table of short module paths
        sys.modules.setdefault(f"tumble.{short}", importlib.import_module(module))


def missing_docstrings():
    """Dotted names of the public objects without a docstring: ``tumble.__all__``, the members of the public
    modules' ``__all__``, and the public methods and properties of the public classes."""
    import tumble

    found = []

    def check(label, obj):
        if inspect.ismodule(obj) or inspect.isclass(obj) or callable(obj) or isinstance(obj, property):
            if not inspect.getdoc(obj):
                found.append(label)
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if attr.startswith("_") or not (inspect.isfunction(member) or isinstance(member, (property,
                                                                                              classmethod,
                                                                                              staticmethod))):
                    continue
                target = member.__func__ if isinstance(member, (classmethod, staticmethod)) else member
                if not inspect.getdoc(target):
                    found.append(f"{label}.{attr}")

    for name in tumble.__all__:
        if name.startswith("_"):
            continue
        obj = getattr(tumble, name)
        check(f"tumble.{name}", obj)
        if inspect.ismodule(obj):
            for member in getattr(obj, "__all__", ()):
                value = getattr(obj, member)
                if not re.fullmatch(r"[A-Z][A-Z0-9_]*", member):  # constants are documented by #: comments
                    check(f"tumble.{name}.{member}", value)
    return found


def _check_docstrings(app):
    for name in missing_docstrings():
        logger.warning(f"public name without a docstring: {name}")


class _Generated(SphinxDirective):
    """A directive whose body is Markdown generated by a function of this module."""

    has_content = False

    def markdown(self):
        raise NotImplementedError

    def run(self):
        return self.parse_text_to_nodes(self.markdown(), allow_section_headings=True)


class ApiReference(_Generated):
    """``tumble-api``: the Python API."""

    def markdown(self):
        return api_reference()


class StudyKeys(_Generated):
    """``tumble-study-keys``: every key of ``studies/defaults.toml``."""

    def markdown(self):
        from tumble.pipeline import schema
        from tumble.pipeline.config import DEFAULTS_PATH

        self.env.note_dependency(str(DEFAULTS_PATH))
        self.env.note_dependency(schema.__file__)
        return study_reference(DEFAULTS_PATH)


class NetcdfReference(_Generated):
    """``tumble-netcdf FILE``: the variables and attributes of a result file."""

    required_arguments = 1

    def markdown(self):
        rel, path = self.env.relfn2path(self.arguments[0])
        self.env.note_dependency(rel)
        return netcdf_reference(path)


def repository_page(path):
    """Where the site carries a file of the repository outside ``docs/`` (``path`` relative to the repository):
    ``("ref", label)`` or ``("doc", page)``, or None. The README is the home page's; a study file is shown on the
    bundled-studies page (:class:`BundledStudies`), a benchmark's results on the benchmark-results page
    (:class:`BenchmarkResults`)."""
    parts = Path(path).parts
    if parts == ("README.md",):
        return "doc", "/index"
    if len(parts) == 2 and parts[0] == "studies" and parts[1].endswith(".toml"):
        return "ref", f"study-{Path(parts[1]).stem}"
    if len(parts) == 3 and parts[:2] == ("benchmarks", "results") and parts[2].endswith(".md"):
        return "ref", f"bench-{Path(parts[2]).stem}"
    return None


class RepositoryLinks(SphinxPostTransform):
    """A Markdown link from a page to a file of the repository outside ``docs/`` (``../README.md``,
    ``../benchmarks/results/attitude.md``, ``../studies/defaults.toml``): right where the pages are read as Markdown
    (GitHub, an editor). On the site it leads to the page that carries the file (:func:`repository_page`), or else
    becomes its link text; a link to a file that does not exist is left to MyST, which fails the build on it."""

    default_priority = 8  # before MyST resolves its references (9) and warns about the unresolved ones

    def run(self, **kwargs):
        source_dir = Path(self.env.srcdir)
        repository = source_dir.parent
        for node in list(self.document.findall(addnodes.pending_xref)):
            if node.get("reftype") != "myst":
                continue
            target = node["reftarget"].split("#")[0]
            page = Path(self.env.doc2path(node.get("refdoc", self.env.docname))).parent
            candidates = [Path(target + suffix) if Path(target).is_absolute() else page / (target + suffix)
                          for suffix in ("", ".md")]
            found = next((c.resolve() for c in candidates if c.resolve().is_file()), None)
            if found is None or found.is_relative_to(source_dir) or not found.is_relative_to(repository):
                continue
            where = repository_page(found.relative_to(repository))
            if where is None:
                node.replace_self(nodes.inline(node.astext(), node.astext()))
                continue
            reftype, reftarget = where
            node["refdomain"], node["reftype"], node["reftarget"] = "std", reftype, reftarget
            node["refexplicit"], node["refwarn"] = True, True
        # MyST makes a link to a file that is no page (studies/defaults.toml) a download: the site shows it instead.
        for node in list(self.document.findall(addnodes.download_reference)):
            found = (Path(self.env.srcdir) / Path(self.env.docname).parent / node["reftarget"]).resolve()
            where = repository_page(found.relative_to(repository)) if found.is_relative_to(repository) else None
            if where is not None and not found.is_relative_to(source_dir):
                xref = addnodes.pending_xref("", *node.children, refdomain="std", reftype=where[0],
                                             reftarget=where[1], refexplicit=True, refwarn=True,
                                             refdoc=self.env.docname)
                node.replace_self(xref)


#: In the command line's help strings (plain text, parsed as reStructuredText by sphinx-argparse): an option name, a
#: quoted install command, an environment variable and a URI template, shown as code.
_HELP_CODE = re.compile(r"""--[a-z][\w-]*|pip install "[^"]*"|\$[A-Z][A-Z0-9_]*|\b[a-z]+://\S+?(?=[ ,;)]|$)""")


class CommandLineLiterals(Transform):
    """In the descriptions of sphinx-argparse's option lists (``docs/reference/cli.md``), the words that are code
    become code: an option (``--scheduler``, which smart quotes would turn into an en dash), ``pip install ".[gpu]"``,
    ``$DASK_SCHEDULER_ADDRESS``; a URI template such as ``tcp://HOST:PORT``, which the parser made a link to nowhere,
    becomes code too. Runs before smart quotes (750)."""

    default_priority = 700

    def apply(self, **kwargs):
        for description in list(self.document.findall(nodes.description)):
            if not isinstance(description.parent, nodes.option_list_item):
                continue
            for ref in list(description.findall(nodes.reference)):
                if not ref.get("refuri", "").startswith(("http://", "https://")):
                    ref.replace_self(nodes.literal(ref.astext(), ref.astext()))
            for text in list(description.findall(nodes.Text)):
                if isinstance(text.parent, nodes.literal) or not _HELP_CODE.search(text):
                    continue
                parts, last = [], 0
                for match in _HELP_CODE.finditer(text):
                    parts += [nodes.Text(text[last:match.start()]), nodes.literal(match.group(), match.group())]
                    last = match.end()
                parts.append(nodes.Text(text[last:]))
                text.parent.replace(text, [part for part in parts if part.astext()])


class Gallery(_Generated):
    """``tumble-gallery FOLDER``: the figures of the bundled studies in ``FOLDER`` (relative to the page)."""

    required_arguments = 1

    def markdown(self):
        _, folder = self.env.relfn2path(self.arguments[0])
        return gallery(folder, Path(self.env.doc2path(self.env.docname)).parent)


class BundledStudies(_Generated):
    """``tumble-bundled-studies``: the defaults file and every bundled study file."""

    def markdown(self):
        from tumble.pipeline.config import DEFAULTS_PATH

        for path in DEFAULTS_PATH.parent.glob("*.toml"):
            self.env.note_dependency(str(path))
        return bundled_studies_page(Path(self.env.doc2path(self.env.docname)).parent)


class BenchmarkResults(_Generated):
    """``tumble-benchmark-results FOLDER``: every results file of the benchmarks (relative to the page)."""

    required_arguments = 1

    def markdown(self):
        _, folder = self.env.relfn2path(self.arguments[0])
        return benchmark_results_page(folder, Path(self.env.doc2path(self.env.docname)).parent)


class Citation(_Generated):
    """``tumble-citation``: how to cite tumble, from the repository's ``CITATION.cff``."""

    def markdown(self):
        path = Path(self.env.srcdir).parent / "CITATION.cff"
        self.env.note_dependency(str(path))
        return citation_page(path)


class Extras(_Generated):
    """``tumble-extras``: the optional dependencies of ``pyproject.toml``."""

    def markdown(self):
        path = Path(self.env.srcdir).parent / "pyproject.toml"
        self.env.note_dependency(str(path))
        return extras_table(path)


def _public_alias(app, env, node, contnode):
    """Resolve a Python reference by the other name of a public module: ``tumble.io.read_dataset`` (the name users
    write) is documented as ``tumble.output.io.read_dataset`` (where it lives), and a docstring may use either."""
    import tumble

    target = node.get("reftarget", "")
    if node.get("refdomain") != "py" or not target.startswith("tumble."):
        return None
    for short, module in tumble._ALIASES.items():  # noqa: SLF001 - the face's own table of short module paths
        for a, b in ((f"tumble.{short}", module), (module, f"tumble.{short}")):
            if target == a or target.startswith(a + "."):
                domain = env.get_domain("py")
                node["reftarget"] = b + target[len(a):]
                found = domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], node["reftarget"],
                                            node, contnode)
                node["reftarget"] = target
                return found
    return None


#: The parts of MathJax 3 the site loads (from the sphinx-mathjax-offline package, which ships MathJax 3.2.2): the
#: TeX-to-HTML component, its fonts and the TeX extensions it loads on demand (``\\boldsymbol``, ...). About 2 MB of
#: the package's 24: the speech and explorer parts of the accessibility menu are left out.
MATHJAX_FILES = ("tex-chtml.js", "output/chtml/fonts/woff-v2", "input/tex/extensions")


def mathjax_folder():
    """The folder of MathJax's files in the installed sphinx-mathjax-offline package (the docs extra)."""
    from sphinx.errors import ExtensionError

    spec = importlib.util.find_spec("sphinx-mathjax-offline")  # the package's module name has hyphens
    if spec is None or not spec.submodule_search_locations:
        raise ExtensionError("the site typesets its equations with a local MathJax: pip install -e \".[docs]\" "
                             "(sphinx-mathjax-offline)")
    return Path(next(iter(spec.submodule_search_locations))) / "static" / "mathjax"


def _local_mathjax(app, config):
    """The pages load MathJax from the site itself (``_static/mathjax/``), never from a CDN: the site reads offline."""
    mathjax_folder()  # fails the build early where the package is missing
    config.mathjax_path = "mathjax/tex-chtml.js"


def _copy_mathjax(app, exception):
    if exception is not None or app.builder.format != "html":
        return
    source, target = mathjax_folder(), Path(app.outdir) / "_static" / "mathjax"
    for part in MATHJAX_FILES:
        if (source / part).is_dir():
            shutil.copytree(source / part, target / part, dirs_exist_ok=True)
        else:
            (target / part).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source / part, target / part)


def _share_navigation_of_pages_outside_the_tree(app):
    """Furo computes the whole sidebar tree for every page (``furo._compute_navigation_tree``), a second per ten
    pages here. For a page in no toctree (an API page of a function or class, a ``[source]`` page, the index) the
    tree marks nothing as current, so it is the same HTML for every such page of one folder: computed once per folder.
    Pages in the tree are left to Furo. Where Furo has no such function (another version), nothing changes."""
    import posixpath

    import furo

    compute = getattr(furo, "_compute_navigation_tree", None)
    if compute is None or getattr(compute, "tumble_shared", False):
        return
    shared = {}

    def navigation_tree(context):
        env, page = app.env, context.get("pagename", "")
        if "included" not in shared:
            shared["included"] = {app.config.root_doc}.union(*env.toctree_includes.values())
        if page in shared["included"]:
            return compute(context)
        folder = posixpath.dirname(page)
        if folder not in shared:
            shared[folder] = compute(context)
        return shared[folder]

    navigation_tree.tumble_shared = True
    furo._compute_navigation_tree = navigation_tree


def setup(app):
    _public_module_aliases()
    app.connect("missing-reference", _public_alias)
    app.connect("builder-inited", write_api_pages)
    app.connect("builder-inited", _share_navigation_of_pages_outside_the_tree)
    app.add_directive("tumble-gallery", Gallery)
    app.add_directive("tumble-bundled-studies", BundledStudies)
    app.add_directive("tumble-citation", Citation)
    app.add_directive("tumble-extras", Extras)
    app.add_directive("tumble-benchmark-results", BenchmarkResults)
    app.add_post_transform(RepositoryLinks)
    app.add_transform(CommandLineLiterals)
    app.add_directive("tumble-api", ApiReference)
    app.add_directive("tumble-study-keys", StudyKeys)
    app.add_directive("tumble-netcdf", NetcdfReference)
    app.connect("builder-inited", _check_docstrings)
    app.connect("config-inited", _local_mathjax)
    app.connect("build-finished", _copy_mathjax)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}

"""The structure gate (issue 23): module size, function complexity and the import graph.

* no module under ``src/`` passes :data:`MAX_LINES` lines;
* no function passes McCabe complexity :data:`MAX_COMPLEXITY` (ruff's C901);
* no import cycle between modules, imports inside functions included (a result's lazy
  ``.plot()`` through ``imubounds.report`` excepted); ``imubounds.io`` imports nothing
  from ``imubounds.dynamic`` or ``imubounds.stationary``; no library module imports
  ``imubounds.cli``.

What still breaks a rule today is listed below with its current figure. The lists can
only shrink: a listed module or function that grew fails, an unlisted one over the limit
fails, and an entry that no longer breaks the rule fails until it is taken off the list.
"""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PACKAGE = "imubounds"

MAX_LINES = 1000
MAX_COMPLEXITY = 25

#: Modules over :data:`MAX_LINES` today (path under src/ -> lines), being split.
LONG_MODULES: dict[str, int] = {
}

#: Functions over :data:`MAX_COMPLEXITY` today ((path under src/, name) -> complexity).
COMPLEX_FUNCTIONS: dict[tuple[str, str], int] = {
}

#: Imports that close a cycle today (importer, imported): none (the format readers take
#: the mount and time matching from io/drive/mount, not from the drive assembly).
CYCLE_EDGES: set[tuple[str, str]] = set()

#: io modules importing from dynamic or stationary today (importer, imported): none
#: (geodesy and the course over ground live in imubounds.geodesy, below io and dynamic).
IO_UPWARD: set[tuple[str, str]] = set()


# --------------------------------------------------------------------------- the graph
def module_files(src: Path, package: str) -> dict[str, Path]:
    """Dotted module name -> file, for every module of ``package`` under ``src``."""
    out: dict[str, Path] = {}
    for p in sorted((src / package).rglob("*.py")):
        parts = list(p.relative_to(src).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return "TYPE_CHECKING" in ast.unparse(test)


def imports_of(name: str, path: Path, modules: Iterable[str]) -> list[tuple[str, str | None]]:
    """``(imported module, enclosing function or None)`` for every import of the module,
    those inside functions included and those under ``if TYPE_CHECKING:`` left out (they
    do not run). ``from a import b`` is an import of ``a.b`` when that is a module."""
    known = set(modules)
    is_pkg = path.name == "__init__.py"
    found: list[tuple[str, str | None]] = []

    def resolve(mod: str) -> str | None:
        while mod and mod not in known and "." in mod:
            mod = mod.rsplit(".", 1)[0]
        return mod if mod in known else None

    def visit(node: ast.AST, func: str | None) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child.test):
                for c in child.orelse:
                    visit(c, func)
                continue
            inner = (
                child.name if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef) else func
            )
            if isinstance(child, ast.Import):
                found.extend((a.name, func) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = name.split(".") if is_pkg else name.split(".")[:-1]
                    base = base[: len(base) - (child.level - 1)]
                    mod = ".".join([*base, *([child.module] if child.module else [])])
                else:
                    mod = child.module or ""
                for a in child.names:
                    sub = f"{mod}.{a.name}"
                    found.append((sub if sub in known else mod, func))
            visit(child, inner)

    visit(ast.parse(path.read_text(encoding="utf-8")), None)
    out = []
    for target, func in found:
        t = resolve(target)
        if t is not None and t != name:
            out.append((t, func))
    return out


@lru_cache(maxsize=4)
def import_graph(src: Path = SRC, package: str = PACKAGE) -> dict[str, set[str]]:
    """Module -> the modules it imports (a result's lazy ``plot*`` import of the report
    package left out). Cached: the callers do not change it."""
    files = module_files(src, package)
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        graph[name] = {
            t for t, func in imports_of(name, path, files)
            if not (func and func.startswith("plot") and t.startswith(f"{package}.report"))
        }  # fmt: skip
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def _edges(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    return {(a, b) for a, targets in graph.items() for b in targets}


# --------------------------------------------------------------------------- the tests
def test_the_cycle_finder_sees_imports_inside_functions(tmp_path: Path) -> None:
    """The check itself: a circle closed by an import inside a function is found; one
    under ``if TYPE_CHECKING`` or in a lazy ``plot()`` into report/ is not."""
    pkg = tmp_path / "pkg"
    (pkg / "report").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg.b import f\n")
    (pkg / "b.py").write_text("def f():\n    from pkg import a\n    return a\n")
    (pkg / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import d\n"
        "class R:\n    def plot(self):\n        from pkg.report import figs\n"
    )
    (pkg / "d.py").write_text("from pkg import c\n")
    (pkg / "report" / "__init__.py").write_text("")
    (pkg / "report" / "figs.py").write_text("from pkg.c import R\n")
    graph = import_graph(tmp_path, "pkg")
    assert cycles(graph) == [["pkg.a", "pkg.b"]], cycles(graph)
    assert graph["pkg.c"] == set() and graph["pkg.d"] == {"pkg.c"}


def test_no_module_passes_1000_lines() -> None:
    sizes = {str(p.relative_to(SRC)): len(p.read_text(encoding="utf-8").splitlines())
             for p in module_files(SRC, PACKAGE).values()}  # fmt: skip
    over = {m: n for m, n in sizes.items() if n > MAX_LINES}
    new = {m: n for m, n in over.items() if m not in LONG_MODULES}
    assert not new, f"modules over {MAX_LINES} lines (split them): {new}"
    grew = {m: (LONG_MODULES[m], n) for m, n in over.items() if n > LONG_MODULES[m]}
    assert not grew, f"listed long modules grew (listed, now): {grew}"
    done = sorted(m for m in LONG_MODULES if sizes.get(m, 0) <= MAX_LINES)
    assert not done, f"take these off LONG_MODULES (now within {MAX_LINES} lines): {done}"


def _ruff_complexity() -> dict[tuple[str, str], int]:
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--isolated", "--select", "C901", "--config",
         f"lint.mccabe.max-complexity={MAX_COMPLEXITY}", "--output-format", "json",
         "--no-cache", "--exit-zero", str(SRC / PACKAGE)],
        capture_output=True, text=True, check=True, cwd=ROOT,
    )  # fmt: skip
    found = {}
    for d in json.loads(proc.stdout):
        m = re.match(r"`(.+)` is too complex \((\d+) > \d+\)", d["message"])
        assert m, d["message"]
        path = str(Path(d["filename"]).resolve().relative_to(SRC))
        found[(path, m.group(1))] = int(m.group(2))
    return found


def test_no_function_passes_complexity_25() -> None:
    found = _ruff_complexity()
    new = {k: v for k, v in found.items() if k not in COMPLEX_FUNCTIONS}
    assert not new, f"functions over McCabe {MAX_COMPLEXITY} (ruff C901; split them): {new}"
    grew = {k: (COMPLEX_FUNCTIONS[k], v) for k, v in found.items() if v > COMPLEX_FUNCTIONS[k]}
    assert not grew, f"listed complex functions grew (listed, now): {grew}"
    done = sorted(k for k in COMPLEX_FUNCTIONS if k not in found)
    assert not done, f"take these off COMPLEX_FUNCTIONS (now within {MAX_COMPLEXITY}): {done}"


def test_no_import_cycle() -> None:
    graph = import_graph()
    edges = _edges(graph)
    stale = sorted(CYCLE_EDGES - edges)
    assert not stale, f"take these off CYCLE_EDGES (the import is gone): {stale}"
    cut = {a: {b for b in t if (a, b) not in CYCLE_EDGES} for a, t in graph.items()}
    left = cycles(cut)
    assert not left, f"import cycles (imports inside functions count): {left}"
    needed = sorted(e for e in CYCLE_EDGES if not cycles({**cut, e[0]: cut[e[0]] | {e[1]}}))
    assert not needed, f"take these off CYCLE_EDGES (they close no cycle now): {needed}"


def test_io_imports_nothing_from_dynamic_or_stationary() -> None:
    up = {(a, b) for a, b in _edges(import_graph())
          if a.startswith(f"{PACKAGE}.io") and b.startswith((f"{PACKAGE}.dynamic",
                                                             f"{PACKAGE}.stationary"))}  # fmt: skip
    assert not up - IO_UPWARD, f"io imports upward: {sorted(up - IO_UPWARD)}"
    assert not IO_UPWARD - up, f"take these off IO_UPWARD: {sorted(IO_UPWARD - up)}"


@pytest.mark.parametrize("layer", ["cli"])
def test_no_library_module_imports_the_command_line(layer: str) -> None:
    cli = f"{PACKAGE}.{layer}"
    bad = sorted((a, b) for a, b in _edges(import_graph())
                 if b.startswith(cli) and not a.startswith(cli)
                 and a != f"{PACKAGE}.__main__")  # fmt: skip
    assert not bad, f"library modules importing the command line: {bad}"


def test_ruff_enforces_the_same_complexity_limit() -> None:
    """``ruff check`` (make lint/test) applies C901 at the same limit, and exempts exactly
    the files of :data:`COMPLEX_FUNCTIONS`."""
    import tomllib

    lint = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["ruff"]
    lint = lint["lint"]
    assert "C901" in lint.get("select", []) + lint.get("extend-select", [])
    assert lint["mccabe"]["max-complexity"] == MAX_COMPLEXITY
    exempt = {f for f, codes in lint.get("per-file-ignores", {}).items() if "C901" in codes}
    assert exempt == {f"src/{path}" for path, _ in COMPLEX_FUNCTIONS}, exempt


def test_drive_formats_register_their_drive_reader_in_the_one_registry() -> None:
    """read_drive finds the ROS-bag, ULog and NMEA drive readers through the reader
    registry (so the drive assembly imports no format reader back); a format without
    one, or an unknown name, is an InputError naming it."""
    from imubounds.errors import InputError
    from imubounds.io.nmea import drive_from_files as nmea_drive
    from imubounds.io.registry import reader_entry
    from imubounds.io.rosbag import drive_from_files as bag_drive
    from imubounds.io.ulog import drive_from_files as ulog_drive

    found = {n: reader_entry(n).load_drive() for n in ("rosbag", "ulog", "nmea")}
    assert found == {"rosbag": bag_drive, "ulog": ulog_drive, "nmea": nmea_drive}
    with pytest.raises(InputError, match="parquet format holds no drive"):
        reader_entry("parquet").load_drive()
    with pytest.raises(InputError, match="no reader 'furlong'"):
        reader_entry("furlong")


def test_drive_reading_is_one_package() -> None:
    """Drive reading lives in io/drive/ (issue 23): the package holds the model under the
    names it always had, its modules sit inside it, and the flat io/drive_*.py are gone."""
    import importlib.util

    import imubounds.io.drive as drive

    assert hasattr(drive, "__path__")
    assert drive.Drive.__module__ == "imubounds.io.drive"
    for name in ("Drive", "DriveSettings", "ImuStream", "GnssStream", "DEFAULT_CEP_M",
                 "DEFAULT_HDOP"):  # fmt: skip
        assert hasattr(drive, name), name
    for mod in ("layout", "settings", "readers", "validate", "mount"):
        assert importlib.util.find_spec(f"imubounds.io.drive.{mod}") is not None, mod
        assert importlib.util.find_spec(f"imubounds.io.drive_{mod}") is None, mod


#: a citation of the project's tracker ("issue 27", "issues 11 and 12", "issue #27"): the
#: tracker is not in the repository, so src cites the docs sections instead
ISSUE_CITATION = re.compile(r"\bissues? *#?\d+", re.IGNORECASE)


def test_src_cites_no_tracker_issue_numbers() -> None:
    found = [
        f"{p.relative_to(SRC)}:{i}: {line.strip()}"
        for p in sorted((SRC / PACKAGE).rglob("*.py"))
        for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
        if ISSUE_CITATION.search(line)
    ]
    assert not found, "\n".join(found)
    assert ISSUE_CITATION.search("(issue 27, items 3 and 5)")
    assert ISSUE_CITATION.search("Issue #12") and not ISSUE_CITATION.search("an issue of 2 s")

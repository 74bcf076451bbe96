"""Importing imubounds has no side effects, and no module reaches into another package's
private names (issue 14, items 4 and the last "done when")."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import imubounds

PACKAGE = Path(imubounds.__file__).resolve().parent

# Runs in a fresh interpreter: snapshot, import imubounds and touch every public name,
# snapshot again. Python's own .pyc writing is switched off (not ours to judge);
# numba, if anything compiled, would write to NUMBA_CACHE_DIR, which is watched.
PROBE = r"""
import json, os, sys
from pathlib import Path

watch = [Path(p) for p in sys.argv[1:]]
pkg = Path(os.environ["PROBE_PACKAGE"])

def tree(root, skip_created=False):
    out = {}
    for dirpath, _, files in os.walk(root):
        for f in files:
            p = Path(dirpath) / f
            if p.suffix == ".pyc":
                continue
            try:
                st = p.stat()
            except FileNotFoundError:
                continue
            out[str(p)] = (st.st_size, st.st_mtime_ns)
    return out

os.umask(0o027)
import matplotlib
raw_backend = dict.__getitem__(matplotlib.rcParams, "backend")
before = {str(r): tree(r) for r in watch}
pkg_before = tree(pkg)

import imubounds
for name in imubounds.__all__:
    getattr(imubounds, name)

after = {str(r): tree(r) for r in watch}
pkg_after = tree(pkg)
mask = os.umask(0o022)
pyplot_imported = "matplotlib.pyplot" in sys.modules  # before get_backend(), which imports it
raw_unchanged = dict.__getitem__(matplotlib.rcParams, "backend") is raw_backend
print(json.dumps({
    "umask": mask,
    "raw_backend_unchanged": raw_unchanged,
    "backend": matplotlib.get_backend(),
    "pyplot_imported": pyplot_imported,
    "changed": {r: sorted(set(before[r].items()) ^ set(after[r].items())) for r in before},
    # other test workers may compile numba code into the package's __pycache__
    # meanwhile (new files, updated indexes): there only deletions are ours to catch
    "package_lost_or_changed": sorted(
        k for k, v in pkg_before.items()
        if k not in pkg_after or ("__pycache__" not in k and pkg_after[k] != v)
    ),
}))
"""


def _probe(tmp_path: Path, mplbackend: str | None) -> dict[str, object]:
    cwd, tmp, numba_dir = tmp_path / "cwd", tmp_path / "tmp", tmp_path / "numba"
    for d in (cwd, tmp, numba_dir):
        d.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    env.update(
        PYTHONDONTWRITEBYTECODE="1",
        TMPDIR=str(tmp),
        NUMBA_CACHE_DIR=str(numba_dir),
        PROBE_PACKAGE=str(PACKAGE),
    )
    if mplbackend is not None:
        env["MPLBACKEND"] = mplbackend
    proc = subprocess.run(
        [sys.executable, "-c", PROBE, str(cwd), str(tmp), str(numba_dir)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stderr == "", f"importing imubounds wrote to stderr: {proc.stderr[-2000:]}"
    result: dict[str, object] = json.loads(proc.stdout.splitlines()[-1])
    return result


@pytest.mark.parametrize("mplbackend", [None, "svg"])
def test_import_and_every_public_name_leave_process_and_files_alone(
    tmp_path: Path, mplbackend: str | None
) -> None:
    r = _probe(tmp_path, mplbackend)
    assert r["umask"] == 0o027, f"umask changed to {r['umask']:o}"
    assert r["raw_backend_unchanged"], f"the matplotlib backend was set: {r['backend']}"
    if mplbackend is not None:
        assert str(r["backend"]).lower() == mplbackend
    assert not r["pyplot_imported"], "importing imubounds imported matplotlib.pyplot"
    changed = r["changed"]
    assert isinstance(changed, dict)
    assert all(not v for v in changed.values()), f"files created or deleted: {changed}"
    assert not r["package_lost_or_changed"], r["package_lost_or_changed"]


def test_default_backend_is_the_one_matplotlib_chooses(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}

    def backend(code: str) -> str:
        out = subprocess.run(
            [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True,
            text=True, timeout=300, check=True,
        )  # fmt: skip
        return out.stdout.strip()

    plain = backend("import matplotlib; print(matplotlib.get_backend())")
    ours = backend("import imubounds, matplotlib; print(matplotlib.get_backend())")
    assert ours == plain


# ------------------------------------------------------------------------ private names


def _package_of(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        return ".".join(parts[:-1])
    return ".".join(parts[:-1])


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _resolve(node: ast.ImportFrom, here: str) -> str:
    if node.level == 0:
        return node.module or ""
    base = here.split(".")
    if node.level > 1:
        base = base[: -(node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _target_package(module: str) -> str:
    """The package (directory) a dotted module name lives in."""
    p = PACKAGE.parent / module.replace(".", "/")
    return module if p.is_dir() else module.rpartition(".")[0]


def private_imports() -> list[str]:
    """``file:line`` of every import of a private name (a ``_name`` or a name inside a
    ``_module``) that lives in another package (directory) of imubounds."""
    found: list[str] = []
    for path in sorted(PACKAGE.rglob("*.py")):
        here = _package_of(path)
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            pairs: list[tuple[str, str]] = []  # (module, name imported from it or "")
            if isinstance(node, ast.ImportFrom):
                mod = _resolve(node, here)
                pairs = [(mod, a.name) for a in node.names]
            elif isinstance(node, ast.Import):
                pairs = [(a.name, "") for a in node.names]
            for mod, name in pairs:
                if mod.split(".")[0] != "imubounds":
                    continue
                full = f"{mod}.{name}" if name else mod
                parts = full.split(".")
                for i in range(1, len(parts)):
                    if not _is_private(parts[i]):
                        continue
                    owner = ".".join(parts[:i])  # the module or package that owns it
                    owner_pkg = owner if (PACKAGE.parent / owner.replace(".", "/")).is_dir() \
                        else _target_package(owner)
                    if owner_pkg != here:
                        found.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}: {full}")
                    break
    return found


def test_no_module_imports_a_private_name_from_another_package() -> None:
    bad = private_imports()
    assert not bad, "private names imported across packages:\n" + "\n".join(bad)


def test_the_private_name_scan_finds_a_violation(tmp_path: Path) -> None:
    """The scan is not vacuous: the two patterns it exists for are recognised."""
    here = "imubounds.cli"
    node = ast.parse("from imubounds.dynamic.estimator.result import _states").body[0]
    assert isinstance(node, ast.ImportFrom)
    assert _resolve(node, here) == "imubounds.dynamic.estimator.result"
    assert _target_package("imubounds.dynamic.estimator.result") == "imubounds.dynamic.estimator"
    assert _is_private("_states") and not _is_private("__version__")
    rel = ast.parse("from ..interval import _core").body[0]
    assert isinstance(rel, ast.ImportFrom)
    assert _resolve(rel, "imubounds.dynamic") == "imubounds.interval"

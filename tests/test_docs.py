"""The documentation site builds without a warning (mkdocs --strict), and its API
reference and pages are complete."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]


def test_every_page_is_in_the_nav_and_every_nav_entry_exists() -> None:
    text = (REPO / "mkdocs.yml").read_text(encoding="utf-8")
    conf = yaml.safe_load(text)
    nav = [next(iter(item.values())) for item in conf["nav"]]
    pages = sorted(p.name for p in (REPO / "docs").glob("*.md"))
    assert sorted(nav) == pages
    for required in ("index.md", "tutorial.md", "static-method.md", "dynamic-method.md",
                     "formats.md", "schemas.md", "api.md"):  # fmt: skip
        assert required in nav, required


def test_api_page_documents_every_public_function_and_result() -> None:
    import imubounds

    text = (REPO / "docs" / "api.md").read_text(encoding="utf-8")
    documented = {line.split(".")[-1].strip() for line in text.splitlines()
                  if line.startswith(":::")}  # fmt: skip
    public = {n for n in imubounds.__all__ if not n.startswith("_")}
    errors = {"ImuboundsError", "InputError", "UnitsError", "OptionError", "AnalysisError",
              "OutputError"}  # fmt: skip
    # the errors come with their module; SimResult, DriveSettings are the simulator's and
    # the drive's own classes, reached from their pages
    missing = public - documented - errors - {"SimResult", "DriveSettings", "errors"}
    assert not missing, f"not in docs/api.md: {sorted(missing)}"


def test_site_builds_without_warnings(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(REPO / "mkdocs.yml"),
         "-d", str(tmp_path / "site")],
        cwd=REPO, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert "WARNING" not in proc.stderr, proc.stderr[-4000:]
    api = (tmp_path / "site" / "api" / "index.html").read_text(encoding="utf-8")
    for anchor in ("api.read_log", "api.characterize", "dynamic.estimator.api.dynamic_margins",
                   "stationary.allan.AllanResult", "stationary.pipeline.StaticResult"):
        assert f'id="imubounds.{anchor}"' in api, anchor
    assert (tmp_path / "site" / "tutorial" / "index.html").is_file()
    # docstrings' Sphinx roles are shown as code, not as raw ':class:' markup
    import re

    for page in (tmp_path / "site").rglob("index.html"):
        html = page.read_text(encoding="utf-8")
        raw = re.findall(r":(?:class|func|meth|mod|attr|data|exc):<code>", html)
        assert not raw, (page, raw[:3])
    assert "<code>ImuLog</code>" in api
    assert 'id="imubounds.api.export_noise"' in api
    assert (tmp_path / "site" / "export" / "index.html").is_file()


# options of other programs named in the docs (not imubounds'), with where they belong
_FOREIGN_OPTIONS = {
    "--strict": "mkdocs build",
    "--nworkers": "dask worker",
    "--nthreads": "dask worker",
    "--partition": "Slurm (dask-jobqueue job_extra_directives)",
}
#: the benchmarks' own options the docs name, and the script that defines each
_BENCH_OPTIONS = {
    "--repeat": "bench_fleet.py",
    "--pairs": "bench_fleet.py",
}


def _cli_options() -> tuple[dict[str, set[str]], set[str]]:
    import argparse

    from imubounds.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    per = {name: {o for a in sp._actions for o in a.option_strings}
           for name, sp in sub.choices.items()}  # fmt: skip
    top = {o for a in parser._actions for o in a.option_strings}
    return per, top.union(*per.values())


def test_every_option_named_in_readme_and_docs_exists() -> None:
    import re

    per, every = _cli_options()
    for o, script in _BENCH_OPTIONS.items():
        bench = (REPO / "benchmarks" / script).read_text(encoding="utf-8")
        assert f'"{o}"' in bench, (o, script)
    known = every | set(_FOREIGN_OPTIONS) | set(_BENCH_OPTIONS)
    tok = re.compile(r"(?<![\w/-])--[a-z][a-z0-9]*(?:-[a-z0-9]+)*")
    bad: list[str] = []
    for f in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        for i, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
            where = f"{f.name}:{i}"
            bad += [f"{where}: {o} is no imubounds option" for o in tok.findall(line)
                    if o not in known]  # fmt: skip
            # a command line (code) names the options of its own command
            m = re.match(r"\s*(?:\$ )?imubounds ([a-z-]+)\b(.*)", line)
            if m and m.group(1) in per:
                bad += [f"{where}: {o} is not an option of 'imubounds {m.group(1)}'"
                        for o in tok.findall(m.group(2))
                        if o in every and o not in per[m.group(1)]]  # fmt: skip
    assert not bad, "\n".join(bad)


def test_the_renamed_options_are_gone_from_the_docs() -> None:
    per, _ = _cli_options()
    assert "--gnss-cep" in per["dynamic"] and "--gps-cep" not in per["dynamic"]
    assert "--reverses" in per["dynamic"]
    text = (REPO / "README.md").read_text(encoding="utf-8")
    assert "dynamic" in text and "--gnss-cep" in text


# where a short reference of docs/dynamic-method.md (`module.function`) is looked up
_REF_BASES = ("imubounds.dynamic.estimator.", "imubounds.dynamic.",
              "imubounds.")  # fmt: skip
_FILE_SUFFIXES = {"json", "yaml", "yml", "csv", "py", "md", "png", "svg", "html", "gz"}


def _resolve_code_ref(ref: str) -> str | None:
    """None when ``ref`` names no module (a drive.yaml or dynamic.json key); "ok" when it
    names an attribute of the module at its head that is defined there (not a re-export);
    else what is wrong."""
    import importlib
    import importlib.util
    import types

    parts = ref.split(".")
    bases = ("imubounds.",) if parts[0] == "imubounds" else _REF_BASES
    if parts[0] == "imubounds":
        parts = parts[1:]
    for base in bases:
        for i in range(len(parts), 0, -1):
            name = base + ".".join(parts[:i])
            try:
                found = importlib.util.find_spec(name) is not None
            except ModuleNotFoundError:
                found = False
            if not found:
                continue
            obj: object = importlib.import_module(name)
            home = obj
            for a in parts[i:]:
                if not hasattr(obj, a):
                    return f"{name} has no {'.'.join(parts[i:])}"
                obj = getattr(obj, a)
                if isinstance(obj, types.ModuleType):
                    home = obj
                    continue
                where = getattr(obj, "__module__", None)
                if (callable(obj) and isinstance(where, str)
                        and where != getattr(home, "__name__", None)):  # fmt: skip
                    return f"{a} is defined in {where}, not in {home.__name__}"  # type: ignore[attr-defined]
                break
            return "ok"
    return None


def test_every_code_reference_of_the_dynamic_method_exists() -> None:
    """Every backticked `module.function` of docs/dynamic-method.md names a function where it
    is defined (issue 23: each equation names the one function that computes it)."""
    import re

    text = (REPO / "docs" / "dynamic-method.md").read_text(encoding="utf-8")
    refs = set(re.findall(r"`([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)+)`", text))
    refs = {r for r in refs if r.rsplit(".", 1)[1] not in _FILE_SUFFIXES}
    results = {r: _resolve_code_ref(r) for r in sorted(refs)}
    bad = [f"{r}: {v}" for r, v in results.items() if v not in (None, "ok")]
    assert not bad, "\n".join(bad)
    assert sum(v == "ok" for v in results.values()) >= 60, results
    # the check itself can fail: a made-up name, and a re-export named in place of the home
    assert _resolve_code_ref("smoother.no_such_function") not in (None, "ok")
    assert _resolve_code_ref("inputs.gnss_outliers") not in (None, "ok")
    assert _resolve_code_ref("sensors.gnss.gnss_outliers") == "ok"


def test_a_broken_link_or_anchor_fails_the_docs_build(tmp_path: Path) -> None:
    """The site's link checks (mkdocs.yml ``validation``: every kind at ``warn``, and
    ``strict``) make a broken anchor or a link to a missing page an error of ``make docs``:
    a two-page site with those settings fails on each and builds without them."""
    conf = yaml.safe_load((REPO / "mkdocs.yml").read_text(encoding="utf-8"))
    assert conf["strict"] is True
    assert conf["validation"] == {k: "warn" for k in (
        "omitted_files", "absolute_links", "unrecognized_links", "anchors")}

    def build(link: str) -> subprocess.CompletedProcess[str]:
        site = tmp_path / link.replace("/", "_").replace("#", "_").replace(".", "_")
        (site / "docs").mkdir(parents=True)
        (site / "docs" / "index.md").write_text(f"# Home\n\nSee [there]({link}).\n")
        (site / "docs" / "other.md").write_text("# Other\n\n## A section {#kept}\n")
        (site / "mkdocs.yml").write_text(yaml.safe_dump({
            "site_name": "t", "strict": True, "validation": conf["validation"],
            "markdown_extensions": ["attr_list"], "nav": ["index.md", "other.md"]}))
        return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f",
                               str(site / "mkdocs.yml"), "-d", str(site / "site")],
                              capture_output=True, text=True, timeout=300)  # fmt: skip

    assert build("other.md#kept").returncode == 0
    bad_anchor = build("other.md#gone")
    assert bad_anchor.returncode != 0 and "does not contain an anchor" in bad_anchor.stderr
    assert build("missing.md").returncode != 0

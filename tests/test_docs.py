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

"""docs/ is the user manual: pages and the figures they show. Results (JSON, plots no page shows) live
in results/<study>/, the benchmarks write there by default, and no page grows into a lab notebook."""

from __future__ import annotations

import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
MAX_PAGE_LINES = 500
IMAGE = re.compile(r"!\[[^\]]*\]\(([^)\s]+\.png)\)")


def _shown_pngs() -> set[Path]:
    """Every PNG a page (or the README) shows, resolved against the page that shows it."""
    shown = set()
    for page in [*DOCS.rglob("*.md"), ROOT / "README.md"]:
        for target in IMAGE.findall(page.read_text()):
            shown.add(Path(os.path.normpath(page.parent / target)))
    return shown


def test_docs_hold_no_result_files():
    data = sorted(p.relative_to(ROOT).as_posix() for ext in ("json", "csv", "npz", "pt") for p in DOCS.rglob(f"*.{ext}"))
    assert not data, f"result files belong in results/<study>/, not docs/: {data}"


def test_every_png_in_docs_is_shown_by_a_page():
    shown = _shown_pngs()
    unshown = sorted(p.relative_to(ROOT).as_posix() for p in DOCS.rglob("*.png") if p not in shown)
    assert not unshown, f"PNGs no page shows belong in results/<study>/: {unshown}"
    missing = sorted(p.relative_to(ROOT).as_posix() for p in shown if not p.is_file())
    assert not missing, f"pages show PNGs that are not there: {missing}"


def test_no_page_is_over_the_limit():
    long = {p.relative_to(ROOT).as_posix(): n for p in DOCS.rglob("*.md") if (n := len(p.read_text().splitlines())) > MAX_PAGE_LINES}
    assert not long, f"pages over {MAX_PAGE_LINES} lines (split the manual from the results): {long}"


def test_results_are_filed_by_study():
    studies = [p for p in (ROOT / "results").iterdir() if p.is_dir()]
    assert len(studies) >= 5 and (ROOT / "results" / "README.md").is_file()
    assert not [p for p in (ROOT / "results").glob("*.json")], "a result file goes in its study's folder"
    readme = (ROOT / "results" / "README.md").read_text()
    for study in studies:
        assert f"`{study.name}/`" in readme, f"results/README.md does not describe {study.name}/"


def test_benchmarks_never_write_into_docs_by_default():
    assert len(list((ROOT / "benchmarks" / "speed").glob("*.py"))) >= 5  # the speed scripts have a folder of their own
    defaults = [f"{p.name}: {m.group(0)}" for p in (ROOT / "benchmarks").rglob("*.py")  # benchmarks/speed/ too
                for m in re.finditer(r"default=(?:Path\()?[\"']docs\b[^\"']*[\"']", p.read_text())]
    assert not defaults, defaults

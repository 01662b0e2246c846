"""The README and the docs as a user meets them: links resolve, the quick start and the demo run."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "bench" / "results" / "index.md"]


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(page):
    missing = []
    for link in re.findall(r"\]\(([^)#\s]+)", page.read_text(encoding="utf-8")):
        if "://" in link:
            continue
        if not (page.parent / link).resolve().exists():
            missing.append(link)
    assert not missing, f"{page.name} links to missing files: {missing}"


@pytest.mark.slow
def test_the_readme_quick_start_runs_and_meets_the_calibration_target(tmp_path):
    code = _python_blocks((ROOT / "README.md").read_text(encoding="utf-8"))[0]
    script = tmp_path / "quickstart.py"
    script.write_text(code, encoding="utf-8")
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=tmp_path, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    heldout = ast.literal_eval(run.stdout.splitlines()[0])  # the first print: the held-out metrics
    assert heldout["r2_t"] >= 0.95 and abs(heldout["nmbe_q_percent"]) <= 5.0
    assert "realised_savings_percent" in run.stdout


@pytest.mark.slow
def test_make_demo_writes_its_report_and_figures(tmp_path):
    from buildenv.cli.main import main

    assert main(["demo", "--out", str(tmp_path)]) in (0, None)
    report = (tmp_path / "report.md").read_text(encoding="utf-8")
    assert "realised" in report.lower()
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    assert {"site/calibration.png", "pareto.png", "before_after.png", "diagnosis.png"} <= set(images)
    for name in images:
        assert (tmp_path / name).stat().st_size > 0, name

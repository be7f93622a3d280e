"""`touchdown bench sweep`: the sweep's cost against its accuracy (bench/sweep_precision.py).

What a designer reads off it: the default settings end the envelope's cases as the fine
reference does, the coarse ones do not always, and the table and the chart are written."""
import subprocess
import sys
from pathlib import Path

import pytest

from touchdown.bench import sweep_precision

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep-precision")
    return out, sweep_precision.main(quick=True, cases=80, out_dir=str(out))


def test_the_default_ends_the_cases_as_the_fine_reference_does(rows):
    _, got = rows
    default = next(r for r in got if r["label"] == "default")
    assert default["n"] == 80
    assert default["differ"] <= 1
    median, p90 = default["t_outcome"]
    assert median < 1e-3 and p90 < 1e-2  # an outcome's instant to a tenth of a percent
    assert default["slide_distance"][0] < 1e-3


def test_the_coarsest_setting_is_cheaper_and_further_off(rows):
    _, got = rows
    default = next(r for r in got if r["label"] == "default")
    coarse = got[-1]
    assert coarse["label"] == "seed's method, 50 ms"
    assert coarse["ms_per_case"] < default["ms_per_case"]
    assert coarse["t_outcome"][0] > 10 * default["t_outcome"][0]
    assert coarse["slide_distance"][0] > 10 * default["slide_distance"][0]


def test_the_table_and_the_chart_are_written(rows):
    out, got = rows
    text = (out / "sweep_precision.md").read_text()
    for r in got:
        assert f"| {r['label']} |" in text
    assert (out / "sweep_precision.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_command_says_what_it_measured(tmp_path):
    proc = subprocess.run([sys.executable, str(ROOT / "cli.py"), "bench", "sweep", "--cases",
                           "4", "--rounds", "1", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "4 envelope cases a setting" in proc.stdout
    assert "CPU ms a case" in proc.stdout and "cores" in proc.stdout

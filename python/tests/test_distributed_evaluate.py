"""gissar.distributed_evaluate: Monte-Carlo trials of `evaluate` spread over a 2-worker Dask LocalCluster
(processes, loopback) give the serial run's table for the same seed."""
import os
import pathlib

import pytest

import gissar

distributed = pytest.importorskip("distributed")
import gissar.distributed_evaluate as de  # noqa: E402

SOURCE = pathlib.Path(os.environ.get("GISSAR_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
DEM = str(SOURCE / "data" / "andorra" / "andorra_srtm3_dem_filled.tif")
# Small and fast: 4 trials of 64 x 64 images at 60 m, one matcher.
SMALL = dict(dem=DEM, trials=4, seed=3, spacing_m=60.0, size_px=64, compare_matchers=False,
             prior_error_horizontal_m=100.0, prior_error_vertical_m=20.0, prior_error_heading_deg=1.0)
TIMING = {"seconds_per_fix"}  # how long a fix took: the only key that may differ


def table(summary):
    return {k: v for k, v in summary.items() if k not in TIMING}


def test_trial_chunks_cover_every_trial_once():
    assert de.trial_chunks(10, 3) == [(0, 3), (3, 3), (6, 3), (9, 1)]
    assert de.trial_chunks(2, 5) == [(0, 2)]
    with pytest.raises(ValueError):
        de.trial_chunks(0, 1)


def test_subsets_summarise_to_the_serial_table():
    serial = gissar.evaluate(**SMALL)
    assert serial["trials"] == 4
    assert 0.0 <= serial["success_rate"] <= 1.0
    first = gissar.evaluate_trials(**SMALL, trial_first=0, trial_count=1)
    rest = gissar.evaluate_trials(**SMALL, trial_first=1, trial_count=-1)
    assert [r["trial"] for r in first + rest] == [0, 1, 2, 3]
    # Any order: the summary sorts by trial.
    assert table(gissar.summarise_trials(rest + first, **SMALL)) == table(serial)
    with pytest.raises(gissar.ConfigError):
        gissar.summarise_trials(first + first, **SMALL)
    with pytest.raises(gissar.ConfigError):
        gissar.evaluate_trials(**SMALL, trial_first=4)


def test_distributed_equals_serial_on_two_workers(tmp_path):
    serial = gissar.evaluate(**SMALL)
    spread = de.evaluate(**SMALL, workers=2, chunk_trials=1, out_prefix=tmp_path / "spread")
    assert table(spread)["success_rate"] == serial["success_rate"]
    for key in table(serial):
        assert spread[key] == serial[key], key
    rows = (tmp_path / "spread_trials.csv").read_text().splitlines()
    assert len(rows) == 5 and rows[1].startswith("0,") and rows[4].startswith("3,")
    assert (tmp_path / "spread_hist.png").exists()


def test_product_trials_spread_over_workers(tmp_path):
    # evaluate --product (a real UAVSAR chip) through the same trial records: two workers, one trial a task.
    product = dict(product=str(SOURCE / "data" / "uavsar" / "SanAnd_129.h5"),
                   dem=str(SOURCE / "data" / "uavsar" / "SanAnd_dem.tif"), trials=3, seed=2)
    serial = gissar.evaluate(**product)
    spread = de.evaluate(**product, workers=2, chunk_trials=1, out_prefix=tmp_path / "product")
    for key in ("success_rate", "converged_rate", "position_error_m", "position_error_cells", "covariance_check",
                "prior_errors", "resolution_cell_m"):
        assert spread[key] == serial[key], key
    rows = (tmp_path / "product_trials.csv").read_text().splitlines()
    assert len(rows) == 4 and rows[1].startswith("0,") and rows[3].startswith("2,")

"""A small typed use of the gissar package: `mypy --strict` checks it against the type hints (.pyi) (ctest python_typing).
Not run: only type-checked."""
from pathlib import Path
from typing import Any, Dict, List

import numpy as np
import numpy.typing as npt
import xarray as xr

import gissar
import gissar.distributed_evaluate


def image_of(dem: Path) -> npt.NDArray[np.float32]:
    da: xr.DataArray = gissar.simulate(dem, heading_deg=30.0, depression_deg=40.0, range_spacing_m=30.0,
                                       azimuth_spacing_m=30.0, progress=True)
    return np.asarray(da.sel(band="total").values, dtype=np.float32)


def from_array(heights: npt.NDArray[np.float32]) -> xr.DataArray:
    sim = gissar.simulate(heights, transform=(400000.0, 30.0, 0.0, 4700000.0, 0.0, -30.0), crs=32631,
                          heading_deg=0.0, depression_deg=40.0, nodata=-9999.0, out_prefix=Path("out/s"))
    return gissar.geocode(sim, "out/m", crs=32631, pixel_size_m=30.0)


def scene_pose(prefix: str) -> Dict[str, Any]:
    scene: gissar.Scene = gissar.Scene.build("dem.tif", prefix, window=(0, 0, 10, 10))
    sim = scene.simulate(heading_deg=0.0, depression_deg=40.0)
    g: gissar.SarGeometry = gissar.SarGeometry(heading_deg=0.0, depression_deg=40.0)
    pixels: npt.NDArray[np.float64] = g.project(np.zeros((1, 3)))
    centre: List[float] = g.scene_centre_enu_m
    prior = {"heading_deg": 1.0, "slant_range_m": 1e4, "sensor_enu_m": centre}
    fix = gissar.locate(scene, sim, prior, range_spacing_m=30.0, azimuth_spacing_m=30.0, matcher="ncc")
    grey, (low_db, high_db) = gissar.quicklook(sim)
    assert pixels.shape == (1, 2) and grey.dtype == np.uint8 and low_db < high_db
    return fix


def errors() -> str:
    try:
        gissar.simulate("missing.tif", heading_deg=0.0, depression_deg=40.0)
    except gissar.MissingFileError as e:
        return str(e)
    except ValueError as e:
        return str(e)
    raw: Dict[str, Any] = gissar.raw.simulate("dem.tif")
    return gissar.__version__ + str(len(raw))


def evaluation(dem: str) -> float:
    records: List[Dict[str, Any]] = gissar.evaluate_trials(dem=dem, trials=4, trial_first=2, trial_count=2)
    part = gissar.summarise_trials(records, dem=dem, trials=4)
    serial = gissar.evaluate(dem=dem, trials=4, seed=3)
    spread = gissar.distributed_evaluate.evaluate(dem=dem, trials=4, seed=3, workers=2, chunk_trials=1)
    chunks = gissar.distributed_evaluate.trial_chunks(10, 3)
    return float(serial["success_rate"]) + float(spread["success_rate"]) + float(part["success_rate"]) + len(chunks)


def corridor(route: Path) -> int:
    from gissar import corridor as cli
    from gissar import distributed as gd
    poses: List[Dict[str, Any]] = gd.corridor_poses(route, pose_step_m=500.0, headings_deg=[0.0, 90.0])
    catalog: Dict[str, Any] = gd.build_corridor([(1.5, 42.5), (1.6, 42.5)], dem="dem.tif", pose_step_m=500.0,
                                                headings_deg=90.0, out_prefix=Path("out/c"), width=64, height=64,
                                                workers=2, threads=1, progress=None, rays_per_cell=1.0)
    summary: Dict[str, Any] = catalog["gissar:summary"]
    assert gd.pose_id(7, 90.0) == "p0007_h090" and cli.flag_of_field("heading_deg") == "--heading"
    return len(poses) + int(summary["done"]) + cli.main(["--help"])


def open_product(safe: Path) -> float:
    ds: xr.Dataset = gissar.open_product(safe, swath="IW1", burst=2, polarization="VV", radiometry="sigma0",
                                         noise_removal=False)
    return float(ds["sigma0"][0, 0])

# Type hints (PEP 484 .pyi) of gissar.distributed (checked by mypy in the tests: python/tests/typing_usage.py).
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

from . import PathLike, Scene

#: A route: a GeoJSON/CSV path or (lon_deg, lat_deg) pairs.
Route = Union[PathLike, Sequence[Sequence[float]]]
#: Progress of a corridor: True (a tqdm bar on stderr), a callable(stage, done, total) or None.
CorridorProgress = Union[None, bool, Callable[[str, int, int], Optional[bool]]]

STAC_VERSION: str

def read_route(route: Route) -> List[Tuple[float, float]]: ...
def resample_route(points: Sequence[Tuple[float, float]],
                   pose_step_m: float) -> List[Tuple[float, float, float, float]]: ...
def pose_id(index: int, heading_deg: float, digits: int = ...) -> str: ...
def corridor_poses(route: Route, *, pose_step_m: float, headings_deg: Union[float, Sequence[float]],
                   slant_range_m: float = ..., depression_deg: float = ...,
                   look_side: str = ...) -> List[Dict[str, Any]]: ...
def predicted_footprint(pose: Dict[str, Any], width: int, height: int, range_spacing_m: float,
                        azimuth_spacing_m: float, depression_deg: float,
                        look_side: str) -> List[Tuple[float, float]]: ...
def limit_threads(threads: Optional[int]) -> int: ...
AUTO_SIZE_MAX_PX: int
AUTO_SIZE_MIN_PX: int
def auto_image_size(poses: Sequence[Dict[str, Any]], extent: Any, range_spacing_m: float, azimuth_spacing_m: float,
                    depression_deg: float, look_side: str, largest: int = ..., smallest: int = ...) -> int: ...
def summary_line(catalog: Dict[str, Any]) -> str: ...
#: The catalogue's key holding the SHA-256 of its canonical JSON without that key.
CHECKSUM_KEY: str
def catalogue_damage(path: PathLike) -> Optional[str]: ...
def build_corridor(route: Route, *, pose_step_m: float, headings_deg: Union[float, Sequence[float]],
                   out_prefix: PathLike, dem: Optional[PathLike] = ..., scene: Union[None, PathLike, Scene] = ...,
                   width: Optional[int] = ..., height: Optional[int] = ..., client: Any = ..., scheduler: Optional[str] = ...,
                   workers: Optional[int] = ..., threads_per_worker: int = ..., threads: Optional[int] = ...,
                   retries: int = ..., hash_inputs: str = ..., progress: CorridorProgress = ...,
                   log: Optional[Callable[[str], Any]] = ..., report_summary: bool = ..., geocode: bool = ..., depression_deg: float = ..., slant_range_m: float = ...,
                   range_spacing_m: float = ..., azimuth_spacing_m: float = ..., look_side: str = ...,
                   rays_per_cell: float = ..., bounces: int = ..., speckle_looks: float = ..., seed: int = ...,
                   **simulate_keywords: Any) -> Dict[str, Any]: ...

from typing import Any, Dict, Optional

from . import Crs, PathLike, Progress, Raster, Transform

def simulate(dem: Optional[Raster] = ..., *, transform: Optional[Transform] = ..., crs: Optional[Crs] = ...,
             nodata: Optional[float] = ..., progress: Progress = ..., **request: Any) -> Dict[str, Any]: ...
def simulate_product(product: PathLike, *, dem: Optional[Raster] = ..., transform: Optional[Transform] = ...,
                     crs: Optional[Crs] = ..., nodata: Optional[float] = ..., progress: Progress = ...,
                     **request: Any) -> Dict[str, Any]: ...

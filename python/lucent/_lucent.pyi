"""Type stubs of the extension module lucent._lucent (the Rust half of the package; the
public API is lucent's, which wraps it)."""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, "os.PathLike[str]"]

class LucentError(Exception): ...

class Camera:
    width: int
    height: int
    @staticmethod
    def look_at(
        eye: Sequence[float],
        target: Sequence[float],
        up: Sequence[float] = ...,
        *,
        fov: float = 45.0,
        fov_axis: str = "x",
        width: int = 640,
        height: int = 480,
    ) -> Camera: ...
    @staticmethod
    def orthographic(
        eye: Sequence[float], target: Sequence[float], up: Sequence[float] = ..., *, view_height: float = 1.0, width: int = 640, height: int = 480
    ) -> Camera: ...
    @staticmethod
    def from_intrinsics(
        intrinsic: npt.ArrayLike, *, extrinsic: Optional[npt.ArrayLike] = None, pose: Optional[npt.ArrayLike] = None, width: int, height: int
    ) -> Camera: ...
    def with_lens(self, aperture: float, focus_distance: float) -> Camera: ...
    def with_clip(self, near: float, far: float) -> Camera: ...
    def with_size(self, width: int, height: int) -> Camera: ...
    @property
    def forward(self) -> List[float]: ...
    @property
    def eye(self) -> List[float]: ...
    def rays(self) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]: ...

class Scene:
    def __init__(self, *, quality: str = "high", triangle_test: str = "unit") -> None: ...
    def add_mesh(
        self,
        vertices: npt.ArrayLike,
        faces: npt.ArrayLike,
        *,
        transform: Optional[npt.ArrayLike] = None,
        normals: Optional[npt.ArrayLike] = None,
        uvs: Optional[npt.ArrayLike] = None,
        material: Optional[Dict[str, Any]] = None,
        name: Optional[str] = None,
    ) -> int: ...
    def add_shape(
        self,
        kind: str,
        *,
        transform: Optional[npt.ArrayLike] = None,
        center: Optional[Sequence[float]] = None,
        radius: Optional[float] = None,
        material: Optional[Dict[str, Any]] = None,
    ) -> int: ...
    def add_spheres(self, centers: npt.ArrayLike, radii: npt.ArrayLike, *, material: Optional[Dict[str, Any]] = None) -> npt.NDArray[np.int64]: ...
    def add_instances(self, geometry: int, transforms: npt.ArrayLike) -> npt.NDArray[np.int64]: ...
    def add_light(
        self,
        kind: str,
        *,
        color: Tuple[float, float, float] = ...,
        position: Optional[Sequence[float]] = None,
        direction: Optional[Sequence[float]] = None,
        angle: float = 30.0,
    ) -> None: ...
    def set_transforms(self, instances: npt.ArrayLike, transforms: npt.ArrayLike) -> None: ...
    def update_vertices(self, geometry: int, vertices: npt.ArrayLike) -> None: ...
    def remove(self, instances: npt.ArrayLike) -> None: ...
    def set_time(self, t: float) -> None: ...
    def commit(self) -> None: ...
    def geometry_of(self, instance: int) -> int: ...
    def mesh_arrays(self, geometry: int) -> Tuple[np.ndarray, npt.NDArray[np.int32]]: ...
    def default_camera(self, width: Optional[int] = None, height: Optional[int] = None) -> Camera: ...
    bounds: npt.NDArray[np.float64]
    num_instances: int
    num_geometries: int
    num_triangles: int
    instance_ids: npt.NDArray[np.int64]
    transforms: npt.NDArray[np.float64]
    camera: Optional[Camera]
    def _intersect(
        self,
        origins: npt.ArrayLike,
        directions: npt.ArrayLike,
        *,
        tmin: Any = None,
        tmax: Any = None,
        fields: Optional[List[str]] = None,
        coherent: Optional[bool] = None,
        out: Optional[Dict[str, np.ndarray]] = None,
        threads: Optional[int] = None,
    ) -> Dict[str, np.ndarray]: ...
    def occluded(
        self, origins: npt.ArrayLike, directions: npt.ArrayLike, *, tmin: Any = None, tmax: Any = None, coherent: Optional[bool] = None, threads: Optional[int] = None
    ) -> npt.NDArray[np.bool_]: ...
    def _intersect_all(
        self, origins: npt.ArrayLike, directions: npt.ArrayLike, *, tmin: Any = None, tmax: Any = None, max_hits: Optional[int] = None, threads: Optional[int] = None
    ) -> Dict[str, Any]: ...
    def count_hits(
        self, origins: npt.ArrayLike, directions: npt.ArrayLike, *, tmin: Any = None, tmax: Any = None, threads: Optional[int] = None
    ) -> npt.NDArray[np.int32]: ...
    def _trace_camera(self, camera: Camera, *, fields: Optional[List[str]] = None, threads: Optional[int] = None) -> Dict[str, np.ndarray]: ...

class Renderer:
    def __init__(
        self,
        scene: Scene,
        camera: Optional[Camera] = None,
        *,
        width: Optional[int] = None,
        height: Optional[int] = None,
        integrator: str = "path",
        max_depth: Optional[int] = None,
        seed: Optional[int] = None,
        threads: Optional[int] = None,
    ) -> None: ...
    def step(self, spp: int = 1) -> None: ...
    @property
    def image(self) -> npt.NDArray[np.float32]: ...
    @property
    def spp(self) -> int: ...
    def reset(self) -> None: ...

def load(path: _Path, *, strict: bool = False, quality: str = "high", triangle_test: str = "unit", **defines: Any) -> Scene: ...
def render(
    scene: Scene,
    camera: Optional[Camera] = None,
    *,
    width: Optional[int] = None,
    height: Optional[int] = None,
    spp: Optional[int] = None,
    integrator: str = "path",
    max_depth: Optional[int] = None,
    seed: Optional[int] = None,
    aovs: Optional[List[str]] = None,
    denoise: bool = False,
    threads: Optional[int] = None,
) -> Any: ...
def denoise(color: npt.ArrayLike, *, albedo: npt.ArrayLike, normal: npt.ArrayLike, depth: npt.ArrayLike, iterations: Optional[int] = None) -> npt.NDArray[np.float32]: ...
def write_image(path: _Path, image: npt.ArrayLike) -> None: ...
def read_image(path: _Path) -> npt.NDArray[np.float32]: ...
def info() -> Dict[str, Any]: ...
def set_num_threads(n: int) -> None: ...

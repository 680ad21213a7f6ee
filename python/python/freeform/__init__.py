"""FreeForm from Python: mesh-free, reduced-order elastodynamics from skinning eigenmodes of
RKPM kernels.

Everything is SI (m, kg, s, Pa) and float64; points are ``(n, 3)`` numpy arrays. The work is
done by the Rust library (``freeform._native``); long calls release the GIL.

A basis for a bar, evaluated at its own points::

    import freeform
    points = freeform.Geometry.box([0, 0, 0], [1, 0.2, 0.2]).integration_points(2000)
    basis = freeform.build_basis(points, freeform.Material(1e6, 0.45, 1000), modes=8, kernels=200)
    w = basis.weights(points.positions)   # (n, 9): the constant handle, then 8 modes
"""

import json
from os import PathLike
from typing import Any, Optional, Union

from ._native import Basis, Geometry, IntegrationPoints, Material, build_basis
from ._native import simulate_scene_file as _simulate_scene_file

__all__ = [
    "Basis",
    "Geometry",
    "IntegrationPoints",
    "Material",
    "build_basis",
    "simulate_scene_file",
]

PathType = Union[str, "PathLike[str]"]


def simulate_scene_file(
    path: PathType, out_dir: PathType = "freeform-out", cache_dir: Optional[PathType] = None
) -> dict[str, Any]:
    """Run a scene file (TOML or JSON; ``docs/scene-files.md``) and write its frames and
    ``summary.json`` under ``out_dir``; return the summary as a dict (times in ms and s,
    lengths in m, energies in J). Cubatures are cached under ``cache_dir`` when given.

    Raises ``ValueError`` naming the file and field for a bad scene, and the stage for a run
    that fails.
    """
    summary = _simulate_scene_file(
        str(path), str(out_dir), None if cache_dir is None else str(cache_dir)
    )
    return json.loads(summary)

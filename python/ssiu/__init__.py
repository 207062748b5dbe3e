"""ssiu: star-tracker and four-FOG star-inertial unit processing (docs/python.md).

The calls mirror the library and the CLI: ``detect``, ``solve`` (and ``Solver``, which keeps a camera's
catalog loaded), ``Tracker``, ``fuse``, ``allan``, ``read_frame``. Results are dicts with the fields of
the corresponding ``ssiu <command> --json`` output. Frames are 2-D uint8/uint16 numpy arrays (uint16
read in place) or file paths; centroid lists are N x 2..4 float arrays (x_px, y_px[, flux][, sigma_px]).
"""
import json as _json
from collections import OrderedDict as _OrderedDict

from ._ssiu import InputError, Solver, Tracker, allan, detect, fuse, read_frame

__all__ = ["InputError", "Solver", "Tracker", "allan", "detect", "fuse", "read_frame", "solve"]

# solve() keeps the last few Solvers (camera + options -> loaded catalog), so that a loop over frames
# loads the catalog once; Solver(...) gives explicit control.
_SOLVERS = _OrderedDict()
_MAX_SOLVERS = 4


def _solver_for(camera, options):
    cam_key = _json.dumps(camera, sort_keys=True) if isinstance(camera, dict) else str(camera)
    key = (cam_key, tuple(sorted((k, repr(v)) for k, v in options.items())))
    solver = _SOLVERS.pop(key, None)
    if solver is None:
        solver = Solver(camera, **options)
    _SOLVERS[key] = solver
    while len(_SOLVERS) > _MAX_SOLVERS:
        _SOLVERS.popitem(last=False)
    return solver


def solve(image_or_centroids, camera, **options):
    """Lost-in-space solve of a frame or a centroid list: the fields of ``ssiu solve --json``.

    ``camera`` is a dict (camera.json's content) or a path to camera.json; options are the flags of
    ``ssiu solve`` in snake_case (catalog, fov_tolerance_pct, max_false_prob, ...).
    """
    return _solver_for(camera, options).solve(image_or_centroids)

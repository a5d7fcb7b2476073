"""Write the mesh files of ``hyq-mesh-scene.yaml``: a rigid step and a soft foam pad, as STL.

Both are convex solids given by their corners (a trapezoidal prism each), so the hull
of the corners is the closed surface, its flat faces triangulated along shared edges.
Run from anywhere: ``python bench/scenes/mesh-files/make_meshes.py``; the files are small
(under 1 kB each) and committed with the scene.

- ``meshes/step.stl``: a rigid step 5 cm high with a sloped front (a ramp face of
  45 degrees), 0.55 m deep, 1 m wide; object frame at the front of its base.
- ``meshes/foam-pad.stl``: a foam pad 4 cm thick with bevelled edges (2 cm in over its
  height), 0.4 x 0.9 m at its base; body frame at the centre of its base.
"""

from pathlib import Path

import numpy as np
import trimesh

FOLDER = Path(__file__).resolve().parent / "meshes"


def prism(bottom: tuple, top: tuple, height: float) -> trimesh.Trimesh:
    """Closed convex solid between a bottom rectangle at z = 0 and a top one at ``height``.

    Parameters
    ----------
    bottom, top : (x_min, x_max, y_min, y_max), metres, object frame
    height : float, metres
    """
    corners = [(x, y, z) for (x0, x1, y0, y1), z in ((bottom, 0.0), (top, height)) for x in (x0, x1) for y in (y0, y1)]
    return trimesh.convex.convex_hull(np.array(corners))


def main() -> None:
    FOLDER.mkdir(exist_ok=True)
    prism((0.0, 0.6, -0.5, 0.5), (0.05, 0.6, -0.5, 0.5), 0.05).export(FOLDER / "step.stl")
    prism((-0.2, 0.2, -0.45, 0.45), (-0.18, 0.18, -0.43, 0.43), 0.04).export(FOLDER / "foam-pad.stl")


if __name__ == "__main__":
    main()

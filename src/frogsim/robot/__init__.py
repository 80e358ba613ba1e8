"""The robot as a moving body: parameters (Table 1, cranks, palms, water), geometry and mass budget,
the MuJoCo model (MJCF), the parts the water acts on, robot scenarios, and offscreen rendering.
See docs/robot.md."""
from __future__ import annotations

import os


def import_mujoco():
    """``import mujoco``, with a clear error when it fails on the OpenGL backend MUJOCO_GL names.

    MuJoCo loads the backend MUJOCO_GL names when it is imported, and a backend whose system
    library is missing makes the import itself fail (PyOpenGL raises AttributeError, not
    ImportError). The simulation needs no OpenGL: unset MUJOCO_GL, or install the backend.
    """
    try:
        import mujoco
    except ImportError:
        raise
    except Exception as exc:
        from frogsim.errors import SimulationError
        gl = os.environ.get("MUJOCO_GL", "")
        raise SimulationError(
            f"MuJoCo could not be imported with MUJOCO_GL={gl!r} ({type(exc).__name__}: {exc}): unset "
            "MUJOCO_GL (the simulation needs no OpenGL; the animation tries EGL, then OSMesa) or "
            "install the backend (Debian/Ubuntu: egl: libegl1 libgl1-mesa-dri; osmesa: libosmesa6)"
        ) from None
    return mujoco

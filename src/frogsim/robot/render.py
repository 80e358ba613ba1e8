"""Offscreen animation of a robot run: MuJoCo's Renderer without a display, written as a GIF.

MuJoCo picks its OpenGL backend from the environment variable MUJOCO_GL when it is first
imported, so the frames are drawn in a child process (``python -m frogsim.robot.render``) that
tries the backends in turn: the user's MUJOCO_GL if set, else EGL (a GPU or Mesa's EGL), then OSMesa
(pure software). If none works, :func:`render_animation` raises :class:`RenderUnavailable` with
what each backend said and the system packages that provide them (Debian/Ubuntu: ``libegl1`` and
``libgl1-mesa-dri`` for EGL, ``libosmesa6`` for OSMesa).

Muscles are drawn red when pressurised and blue when vented; the palms' membranes open and fold
with the steering motors.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from frogsim.errors import FrogsimError

BACKENDS = ("egl", "osmesa")
APT_PACKAGES = {"egl": "libegl1 libgl1-mesa-dri", "osmesa": "libosmesa6"}


class RenderUnavailable(FrogsimError):
    """No OpenGL backend could draw offscreen on this machine."""


def frames_for(result, fps: float = 20.0, max_frames: int = 600) -> dict:
    """What the worker draws: per frame the MuJoCo positions, palm fan angles and muscle colours."""
    from frogsim.circuit import layout as CL
    from frogsim.robot.geometry import palm_fan_angle
    t = result.t
    duration = float(t[-1] - t[0])
    n = int(min(max_frames, max(2, round(duration * fps) + 1)))
    times = np.linspace(t[0], t[-1], n)
    idx = np.clip(np.searchsorted(t, times), 0, t.size - 1)
    cm = result.model
    c = cm.columns
    qpos = result.rec[idx, c["qpos"]]
    pal = result.rs.robot.palms
    L = result.rs.robot.legs.palm_length
    phi_f, phi_o = palm_fan_angle(pal.folded_area, L), palm_fan_angle(pal.open_area, L)
    fan = phi_f + result.palm_opening[idx] * (phi_o - phi_f)
    patm = cm.pneumatic.g[CL.G_PATM]
    p_max = max(float(cm.rs.pneumatic.source.initial_pressure_gauge), 1.0)
    level = np.clip((result.pressures[idx] - patm) / p_max, 0.0, 1.0)
    captions = np.array([f"{result.rs.name}   t = {tk:5.2f} s   {vk:+.2f} m/s   "
                         f"source {(pk - patm) / 1e5:.1f} bar"
                         for tk, vk, pk in zip(times, result.forward_velocity[idx],
                                               result.source_pressure[idx])])
    return {"xml": np.array(cm.xml), "qpos": qpos, "fan": fan, "level": level,
            "muscles": np.array(result.muscle_names), "captions": captions, "fps": np.array(fps)}


def render_animation(result, path, fps: float = 20.0, width: int = 480, height: int = 360,
                     camera: str = "track", max_frames: int = 600, timeout: float = 600.0) -> Path:
    """Draw the run offscreen and write an animated GIF to ``path`` (atomically).

    Raises RenderUnavailable when no OpenGL backend works (see the module docstring).
    """
    from frogsim._files import atomic_write
    path = Path(path)
    data = frames_for(result, fps, max_frames)
    backends = [os.environ["MUJOCO_GL"]] if os.environ.get("MUJOCO_GL") else list(BACKENDS)
    errors = []
    with tempfile.TemporaryDirectory(prefix="frogsim-render-") as tmp:
        npz = os.path.join(tmp, "frames.npz")
        np.savez(npz, camera=np.array(camera), size=np.array([width, height]), **data)
        gif = os.path.join(tmp, "out.gif")
        for backend in backends:
            env = dict(os.environ, MUJOCO_GL=backend)
            env.pop("PYOPENGL_PLATFORM", None)
            proc = subprocess.run([sys.executable, "-m", "frogsim.robot.render", npz, gif],
                                  env=env, capture_output=True, text=True, timeout=timeout)
            if proc.returncode == 0 and os.path.exists(gif):
                atomic_write(path, lambda t: os.replace(gif, t))
                return path
            last = (proc.stderr.strip().splitlines() or ["no message"])[-1]
            errors.append(f"MUJOCO_GL={backend}: {last}")
    hint = "; ".join(f"{b}: apt-get install {APT_PACKAGES[b]}" for b in backends if b in APT_PACKAGES)
    raise RenderUnavailable("no OpenGL backend could render offscreen (" + " | ".join(errors)
                            + (f"). Install one: {hint}" if hint else ")"))


class SceneRenderer:
    """Draws states of a robot's MJCF offscreen: one MuJoCo Renderer on a model of its own.

    :meth:`draw` takes the MuJoCo positions, the palms' fan angles [rad] (left, right) and each
    muscle's pressure level (0 vented .. 1 full, colouring its tendon blue to red) and returns an
    (height, width, 3) uint8 image from ``camera``. The OpenGL backend is the one MuJoCo chose
    from MUJOCO_GL when it was imported; without one that works, RenderUnavailable says so.
    """

    def __init__(self, xml: str, muscles, width: int, height: int, camera: str = "track"):
        import mujoco
        from frogsim.robot.mjcf import PALM_STRIPS
        self._mujoco = mujoco
        m = mujoco.MjModel.from_xml_string(str(xml))
        self.m, self.d = m, mujoco.MjData(m)
        try:
            self.renderer = mujoco.Renderer(m, int(height), int(width))
        except Exception as exc:        # noqa: BLE001  (the GL libraries raise many kinds)
            gl = os.environ.get("MUJOCO_GL", "unset: MuJoCo's default needs a display")
            hint = "; ".join(f"{b}: apt-get install {p}" for b, p in APT_PACKAGES.items())
            raise RenderUnavailable(f"no OpenGL context for offscreen drawing (MUJOCO_GL={gl}): {exc}. "
                                    f"Set MUJOCO_GL=egl or osmesa before importing frogsim ({hint})") from None
        self.camera = camera
        self.palms = [[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"palm_{side}_membrane{k}")
                       for k in range(PALM_STRIPS)] for side in ("left", "right")]
        self.strip = 2.0 * float(m.geom_size[self.palms[0][0], 0]) * PALM_STRIPS
        self.tendons = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, str(name)) for name in muscles]

    def draw(self, qpos, fan, level) -> np.ndarray:
        from frogsim.robot.mjcf import palm_visual_heights
        m, d = self.m, self.d
        d.qpos[:] = qpos
        for p, gids in enumerate(self.palms):
            for gid, hh in zip(gids, palm_visual_heights(float(fan[p]), self.strip)):
                m.geom_size[gid, 2] = hh
        for i, tid in enumerate(self.tendons):
            a = float(level[i])
            m.tendon_rgba[tid] = (0.2 + 0.75 * a, 0.3 * (1.0 - a) + 0.15, 0.9 * (1.0 - a) + 0.1, 1.0)
        self._mujoco.mj_forward(m, d)
        self.renderer.update_scene(d, camera=self.camera)
        return self.renderer.render()

    def close(self) -> None:
        self.renderer.close()


def _draw(npz: str, gif: str) -> None:
    """Worker: draw every frame with the backend MUJOCO_GL names and save the GIF."""
    from PIL import Image, ImageDraw, ImageFont

    data = np.load(npz)
    width, height = (int(x) for x in data["size"])
    renderer = SceneRenderer(str(data["xml"]), data["muscles"], width, height, str(data["camera"]))
    font = ImageFont.load_default()
    images = []
    for k in range(data["qpos"].shape[0]):
        image = Image.fromarray(renderer.draw(data["qpos"][k], data["fan"][k], data["level"][k]))
        draw = ImageDraw.Draw(image)
        draw.rectangle((0, 0, width, 20), fill=(10, 30, 40))
        draw.text((6, 4), str(data["captions"][k]), fill=(235, 235, 235), font=font)
        images.append(image)
    renderer.close()
    duration = int(round(1000.0 / float(data["fps"])))
    frames = [im.convert("P", palette=Image.Palette.ADAPTIVE, colors=128) for im in images]
    frames[0].save(gif, format="GIF", save_all=True, append_images=frames[1:], duration=duration,
                   loop=0, optimize=True)


if __name__ == "__main__":
    _draw(sys.argv[1], sys.argv[2])

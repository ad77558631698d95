"""Pictures and videos of episodes, drawn by MuJoCo's offscreen renderer.

Any backend's trajectory can be drawn: the recorded root poses and joint
angles are replayed kinematically in a MuJoCo model of the same robot on the
same terrain (``MUJOCO_GL=egl`` works headless; it is set here if unset).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frbench.errors import FrbenchError


@dataclass
class Trajectory:
    """Recorded frames: base_pos (T, 3) [m], base_quat (T, 4) wxyz, q (T, n_joints) [rad]."""

    base_pos: list = field(default_factory=list)
    base_quat: list = field(default_factory=list)
    q: list = field(default_factory=list)

    def add(self, state, row: int = 0) -> None:
        """Append row ``row`` of a `RobotState`."""
        self.base_pos.append(state.base_pos[row].copy())
        self.base_quat.append(state.base_quat[row].copy())
        self.q.append(state.q[row].copy())


class SceneRenderer:
    """Draws a robot on a terrain at given configurations."""

    def __init__(self, spec, terrain, width: int = 640, height: int = 480):
        os.environ.setdefault("MUJOCO_GL", "egl")
        import mujoco

        from frbench.backends.mujoco_model import build_model, joint_addresses

        self._mujoco = mujoco
        self.model = build_model(spec, terrain)
        self.model.vis.global_.offwidth = max(width, self.model.vis.global_.offwidth)
        self.model.vis.global_.offheight = max(height, self.model.vis.global_.offheight)
        self.data = mujoco.MjData(self.model)
        self.qadr, _ = joint_addresses(self.model, spec)
        try:
            self.renderer = mujoco.Renderer(self.model, height=height, width=width)
        except Exception as exc:  # no GL context
            raise FrbenchError(f"cannot open MuJoCo's offscreen renderer (MUJOCO_GL={os.environ.get('MUJOCO_GL')}): {exc}") from None
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.distance = 2.2 * max(spec.nominal_height, 0.3) / 0.3 * 0.6 + 0.8
        self.camera.azimuth, self.camera.elevation = 135.0, -25.0

    def frame(self, base_pos, base_quat, q) -> np.ndarray:
        """An RGB image (H, W, 3) uint8 of one configuration, the camera looking at the base."""
        mujoco = self._mujoco
        self.data.qpos[:3] = base_pos
        self.data.qpos[3:7] = base_quat
        self.data.qpos[self.qadr] = q
        mujoco.mj_forward(self.model, self.data)
        self.camera.lookat[:] = base_pos
        self.renderer.update_scene(self.data, camera=self.camera)
        return self.renderer.render().copy()

    def close(self) -> None:
        """Free the GL context."""
        self.renderer.close()


def write_video(frames: list[np.ndarray], path: Path, fps: int) -> Path:
    """Write frames to ``path`` (.gif or .mp4)."""
    import imageio.v3 as iio

    suffix = path.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise FrbenchError(f"--out {path}: expected a .gif or .mp4 file")
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".gif":
        iio.imwrite(path, np.stack(frames), duration=1000 / fps, loop=0)
    else:
        try:
            iio.imwrite(path, np.stack(frames), fps=fps, codec="libx264", plugin="pyav" if _has("av") else None)
        except Exception as exc:
            raise FrbenchError(f"--out {path}: cannot write MP4 ({exc}); use a .gif path") from None
    return path


def _has(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None

"""Pictures and videos of episodes, drawn by MuJoCo's offscreen renderer.

Any backend's trajectory can be drawn: the recorded root poses and joint
angles are copied into a render-only MuJoCo model of the same robot on the
same terrain and drawn kinematically (``mj_forward``, no physics step).

What the render model adds to the simulation model (`render_model`); the
physics models of both simulators are untouched:

* the robot's visual meshes when its URDF has them (placed by Pinocchio's
  URDF geometry parser, read by assimp: ``.dae``, ``.stl`` and ``.obj``), in a
  group that collides with nothing; the collision primitives are then hidden.
  A URDF without visuals is drawn with its collision shapes;
* a checkered ground and terrain boxes, each box shaded by height and
  alternating in tone with its neighbour, lit from the side so that stair
  treads, risers, stones, gaps and beams read at a glance;
* a camera that follows the base (smoothed) at a fixed azimuth and elevation,
  so the horizon stays level.

`SceneRenderer.frame` can write a caption (time, success state, simulator)
onto the image. Rendering needs an OpenGL context, and MuJoCo picks its GL
platform when it is first imported: code that renders calls `use_headless_gl`
before anything imports mujoco (on Linux it sets ``MUJOCO_GL=egl`` unless set).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from frbench.errors import FrbenchError
from frbench.io import atomic_write_bytes, sha256_text
from frbench.robots.paths import cache_dir, cmeel_share

#: Render group of the visual meshes, and the group the collision shapes move to when meshes are drawn (hidden).
VISUAL_GROUP, HIDDEN_GROUP = 1, 3
#: Colours of the robot when its URDF gives none: the root link, the other links.
ROBOT_BODY_RGBA, ROBOT_LIMB_RGBA = (0.78, 0.80, 0.83, 1.0), (0.22, 0.23, 0.25, 1.0)
#: Two tones that neighbouring terrain boxes alternate between (scaled by height).
TERRAIN_TONES = ((0.95, 0.74, 0.47), (0.62, 0.76, 0.92))
#: Backend name → the simulator's name as captions write it.
SIMULATOR_LABELS = {"mujoco": "MuJoCo", "pybullet": "PyBullet", "physx": "PhysX"}


def use_headless_gl() -> None:
    """On Linux, ``MUJOCO_GL=egl`` unless the variable is set or mujoco is already imported (it reads the
    variable once, at import): offscreen rendering without a display."""
    if sys.platform.startswith("linux") and "mujoco" not in sys.modules:
        os.environ.setdefault("MUJOCO_GL", "egl")


@dataclass
class Trajectory:
    """Recorded frames: base_pos (T, 3) [m], base_quat (T, 4) wxyz, q (T, n_joints) [rad], time (T,) [s] and
    recovered (T,) (the success test passed by then)."""

    base_pos: list = field(default_factory=list)
    base_quat: list = field(default_factory=list)
    q: list = field(default_factory=list)
    time: list = field(default_factory=list)
    recovered: list = field(default_factory=list)

    def add(self, state, row: int = 0, time: float = 0.0, recovered: bool = False) -> None:
        """Append row ``row`` of a `RobotState` at ``time`` [s]."""
        self.base_pos.append(state.base_pos[row].copy())
        self.base_quat.append(state.base_quat[row].copy())
        self.q.append(state.q[row].copy())
        self.time.append(float(time))
        self.recovered.append(bool(recovered))


@dataclass(frozen=True)
class VisualMesh:
    """One visual mesh of a URDF: vertices (V, 3) [m, scaled], faces (F, 3), its placement in the frame of the
    link ``body`` (pos (3,) [m], quat (4,) wxyz) and its colour."""

    body: str
    vertices: np.ndarray
    faces: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    rgba: tuple


#: Bump when `visual_meshes` changes what it extracts (invalidates the cached meshes).
VISUAL_MESH_VERSION = 2


@lru_cache(maxsize=8)
def visual_meshes(urdf_path: str) -> tuple[VisualMesh, ...]:
    """The URDF's visual meshes, each attached to the child link of its moving joint (empty: none, or none that
    loads). Pinocchio resolves ``package://`` against example-robot-data's share folder and the URDF's folders,
    assimp reads the mesh files; the extracted meshes are cached under frbench's cache folder by the URDF's checksum (Go1's 0.7 M triangles
    take seconds to extract)."""
    urdf = Path(urdf_path)
    key = sha256_text(f"{VISUAL_MESH_VERSION}\n{urdf.resolve()}\n{urdf.read_text(errors='replace')}")[:20]
    cached = cache_dir() / "visual-meshes" / f"{urdf.stem}-{key}.npz"
    if cached.is_file():
        try:
            return _meshes_from_arrays(dict(np.load(cached, allow_pickle=False)))
        except (OSError, ValueError, KeyError):
            pass  # unreadable cache: extract again
    meshes = _extract_visual_meshes(urdf)
    try:
        import io

        buffer = io.BytesIO()
        np.savez_compressed(buffer, **_meshes_to_arrays(meshes))
        atomic_write_bytes(cached, buffer.getvalue())
    except FrbenchError:
        pass  # a read-only cache folder only costs time
    return meshes


def _meshes_to_arrays(meshes: tuple[VisualMesh, ...]) -> dict[str, np.ndarray]:
    arrays = {"count": np.array(len(meshes))}
    for k, mesh in enumerate(meshes):
        arrays.update({f"{k}_body": np.array(mesh.body), f"{k}_vertices": mesh.vertices, f"{k}_faces": mesh.faces,
                       f"{k}_pos": mesh.pos, f"{k}_quat": mesh.quat, f"{k}_rgba": np.array(mesh.rgba)})
    return arrays


def _meshes_from_arrays(arrays: dict[str, np.ndarray]) -> tuple[VisualMesh, ...]:
    return tuple(VisualMesh(str(arrays[f"{k}_body"]), arrays[f"{k}_vertices"], arrays[f"{k}_faces"],
                            arrays[f"{k}_pos"], arrays[f"{k}_quat"], tuple(float(c) for c in arrays[f"{k}_rgba"]))
                 for k in range(int(arrays["count"])))


def _extract_visual_meshes(urdf: Path) -> tuple[VisualMesh, ...]:
    """`visual_meshes` without the cache: the visual elements and their placements from Pinocchio's URDF
    geometry parser, each mesh's triangles from assimp (`_mesh_triangles`)."""
    import warnings

    import pinocchio as pin

    try:
        model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            geometry = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.VISUAL,
                                             [str(cmeel_share()), str(urdf.parent), str(urdf.parent.parent)])
    except Exception:  # a URDF whose meshes Pinocchio cannot load: draw its collision shapes instead
        return ()
    link_of_joint = {}
    for frame in model.frames:
        if frame.type == pin.FrameType.BODY:
            link_of_joint.setdefault(frame.parentJoint, frame.name)
    meshes = []
    for item in geometry.geometryObjects:
        shape = item.geometry
        if not item.meshPath or not hasattr(shape, "num_tris") or shape.num_tris == 0:
            continue
        triangles = _mesh_triangles(Path(item.meshPath), np.asarray(shape.vertices(), dtype=float))
        if triangles is None:
            return ()  # one mesh that cannot be read faithfully: draw the collision shapes rather than half a robot
        vertices, faces = triangles
        quat = pin.Quaternion(item.placement.rotation)
        meshes.append(VisualMesh(link_of_joint[item.parentJoint], vertices * np.asarray(item.meshScale), faces,
                                 item.placement.translation.copy(), np.array([quat.w, quat.x, quat.y, quat.z]),
                                 tuple(float(c) for c in item.meshColor)))
    return tuple(meshes)


def _assimp() -> Path | None:
    """assimp's command-line tool, installed with Pinocchio (cmeel-assimp), or None."""
    try:
        tool = cmeel_share().parent / "bin" / "assimp"
    except FrbenchError:
        return None
    return tool if tool.is_file() else None


def _mesh_triangles(path: Path, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices (V, 3) [file units] and faces (F, 3) of a mesh file (.dae, .stl, .obj, ...), every sub-mesh with
    its node transform, converted by assimp to binary STL; None if that fails or disagrees with ``reference``.

    Why assimp's tool and not coal's loader (which Pinocchio used): coal's triangles of a file with several
    sub-meshes index the first sub-mesh's vertices only (Go2's thigh.dae: faces reach 2,089 of 3,037 vertices),
    and MuJoCo's OBJ reader keeps the first object only. assimp turns a Z-up COLLADA file into Y-up; that is
    undone, and the result's bounding box must match that of ``reference`` (coal's vertices, placed right) within
    10 % of its size + 2 mm (a wrong axis convention is off by centimetres).
    """
    import subprocess
    import tempfile

    tool = _assimp()
    if tool is None or not path.is_file():
        return None
    with tempfile.TemporaryDirectory(prefix="frbench-mesh-") as folder:
        target = Path(folder) / "mesh.stl"
        environment = {**os.environ, "LD_LIBRARY_PATH": os.pathsep.join(
            filter(None, [str(tool.parent.parent / "lib"), os.environ.get("LD_LIBRARY_PATH")]))}
        done = subprocess.run([str(tool), "export", str(path), str(target), "-fstlb", "-ptv"], env=environment,
                              capture_output=True, timeout=120)
        if done.returncode != 0 or not target.is_file():
            return None
        data = target.read_bytes()
    count = int(np.frombuffer(data[80:84], dtype="<u4")[0])
    record = np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attribute", "<u2")])
    corners = np.frombuffer(data[84:84 + record.itemsize * count], dtype=record)["vertices"].reshape(-1, 3)
    corners = corners.astype(float)
    if path.suffix.lower() == ".dae" and "<up_axis>Z_UP</up_axis>" in path.read_text(errors="replace").replace(" ", ""):
        corners = np.stack([corners[:, 0], -corners[:, 2], corners[:, 1]], axis=1)  # assimp's Y-up back to Z-up
    tolerance = 0.1 * float(np.ptp(reference, axis=0).max()) + 0.002  # the loaders differ by millimetres
    if not (np.allclose(corners.min(0), reference.min(0), atol=tolerance)
            and np.allclose(corners.max(0), reference.max(0), atol=tolerance)):
        return None
    vertices, inverse = np.unique(np.round(corners, 7), axis=0, return_inverse=True)
    return vertices, inverse.reshape(-1, 3).astype(np.int32)


def _robot_rgba(default: tuple, root: bool) -> list:
    """The URDF's colour, unless it gave none (white or MuJoCo's grey): then frbench's two-tone scheme."""
    if tuple(round(c, 3) for c in default) in ((1.0, 1.0, 1.0, 1.0), (0.5, 0.5, 0.5, 1.0), (0.0, 0.0, 0.0, 0.0)):
        return list(ROBOT_BODY_RGBA if root else ROBOT_LIMB_RGBA)
    return list(default)


def _terrain_rgba(index: int, top: float, low: float, high: float) -> list:
    """Alternating tones, brighter with height, so neighbouring boxes and steps stand apart."""
    shade = 0.7 + 0.3 * (0.5 if high <= low else (top - low) / (high - low))
    tone = TERRAIN_TONES[index % 2]
    return [min(1.0, c * shade) for c in tone] + [1.0]


def render_model(spec, terrain):
    """A render-only ``MjModel`` of ``spec`` on ``terrain`` (see the module docstring) and whether it draws the
    robot's visual meshes."""
    import mujoco

    from frbench.backends.mujoco_model import build_spec

    mj = build_spec(spec, terrain)
    mj.compiler.discardvisual = False  # the URDF default would drop every geom that collides with nothing
    root = mj.worldbody.first_body().name
    robot_geoms = [g for g in mj.geoms if g.parent.name != "world"]
    terrain_geoms = [g for g in mj.geoms if g.parent.name == "world"]
    meshes = visual_meshes(str(spec.urdf_path))
    for geom in mj.geoms:
        geom.contype, geom.conaffinity = 0, 0
    for geom in robot_geoms:
        geom.rgba = list(ROBOT_BODY_RGBA if geom.parent.name == root else ROBOT_LIMB_RGBA)
        if meshes:
            geom.group = HIDDEN_GROUP
    for k, mesh in enumerate(meshes):
        asset = mj.add_mesh()
        asset.name = f"frbench_visual_{k}"
        asset.uservert = mesh.vertices.ravel().tolist()
        asset.userface = mesh.faces.ravel().tolist()
        mj.body(mesh.body).add_geom(name=f"frbench_visual_{k}", type=mujoco.mjtGeom.mjGEOM_MESH,
                                     meshname=asset.name, pos=mesh.pos.tolist(), quat=mesh.quat.tolist(),
                                     rgba=_robot_rgba(mesh.rgba, mesh.body == root), group=VISUAL_GROUP,
                                     contype=0, conaffinity=0)
    grid = mj.add_texture(name="frbench_grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                          builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=256, height=256,
                          rgb1=[0.93, 0.93, 0.93], rgb2=[0.80, 0.81, 0.83],
                          mark=mujoco.mjtMark.mjMARK_EDGE, markrgb=[0.35, 0.35, 0.38])
    material = mj.add_material(name="frbench_grid", texrepeat=[2.0, 2.0], texuniform=True)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = grid.name
    mj.add_texture(name="frbench_sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                   builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=64, height=64,
                   rgb1=[0.62, 0.74, 0.88], rgb2=[0.95, 0.96, 0.98])
    tops = [box.top_z for box in terrain.boxes]
    low, high = (min(tops), max(tops)) if tops else (0.0, 0.0)
    for geom in terrain_geoms:
        geom.material = material.name
        if geom.name.startswith("terrain_box_"):
            index = int(geom.name.rsplit("_", 1)[1])
            geom.rgba = _terrain_rgba(index, tops[index], low, high)
        else:
            geom.rgba = [1.0, 1.0, 1.0, 1.0]
    for light in list(mj.lights):
        mj.delete(light)
    sun = mj.worldbody.add_light(name="frbench_sun", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                                 dir=[0.35, 0.2, -0.91], diffuse=[0.8, 0.8, 0.76], specular=[0.1, 0.1, 0.1],
                                 castshadow=False)
    sun.ambient = [0.22, 0.22, 0.24]
    mj.visual.headlight.ambient = [0.12, 0.12, 0.12]
    mj.visual.headlight.diffuse = [0.18, 0.18, 0.18]
    mj.visual.headlight.specular = [0.0, 0.0, 0.0]
    mj.visual.quality.offsamples = 0  # multisampling would cost 2.4x the CPU time per frame with software GL
    return mj.compile(), bool(meshes)


class SceneRenderer:
    """Draws a robot on a terrain at given configurations (``frame``), the camera following the base."""

    def __init__(self, spec, terrain, width: int = 640, height: int = 480):
        use_headless_gl()
        import mujoco

        from frbench.backends.mujoco_model import joint_addresses

        self._mujoco = mujoco
        self.model, self.draws_visuals = render_model(spec, terrain)
        self.model.vis.global_.offwidth = max(width, self.model.vis.global_.offwidth)
        self.model.vis.global_.offheight = max(height, self.model.vis.global_.offheight)
        self.model.vis.map.znear = 0.01
        self.data = mujoco.MjData(self.model)
        self.qadr, _ = joint_addresses(self.model, spec)
        try:
            self.renderer = mujoco.Renderer(self.model, height=height, width=width)
        except Exception as exc:  # no GL context
            gl = os.environ.get("MUJOCO_GL", "unset")
            raise FrbenchError(f"cannot open MuJoCo's offscreen renderer (MUJOCO_GL={gl}; headless, set MUJOCO_GL=egl "
                               f"before mujoco is imported): {exc}") from None
        self.options = mujoco.MjvOption()
        self.options.geomgroup[:] = 0
        self.options.geomgroup[0] = 1
        self.options.geomgroup[VISUAL_GROUP] = 1
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        size = max(spec.nominal_height, 0.3)
        self.camera.distance = 0.8 + 2.2 * size
        self.camera.azimuth, self.camera.elevation = 105.0, -16.0
        self._lookat: dict = {}
        self.follow = 0.15  # fraction of the way the camera's target moves towards the base each frame

    def frame(self, base_pos, base_quat, q, caption: str | None = None, track=0) -> np.ndarray:
        """An RGB image (H, W, 3) uint8 of one configuration, the camera following the base; ``caption`` is
        written in the top-left corner. ``track`` names the followed robot (one smoothed camera target per
        name, e.g. one per environment of a batch)."""
        mujoco = self._mujoco
        self.data.qpos[:3] = base_pos
        self.data.qpos[3:7] = base_quat
        self.data.qpos[self.qadr] = q
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)  # light directions
        target = np.asarray(base_pos, dtype=float)
        previous = self._lookat.get(track)
        lookat = target.copy() if previous is None else previous + self.follow * (target - previous)
        self._lookat[track] = lookat
        self.camera.lookat[:] = lookat
        self.renderer.update_scene(self.data, camera=self.camera, scene_option=self.options)
        image = self.renderer.render()
        return draw_caption(image, caption) if caption else image.copy()

    def forget(self, track=0) -> None:
        """The next frame of ``track`` puts the camera straight on the base (a new episode)."""
        self._lookat.pop(track, None)

    def close(self) -> None:
        """Free the GL context."""
        self.renderer.close()


def draw_caption(image: np.ndarray, text: str) -> np.ndarray:
    """``image`` (H, W, 3) uint8 with ``text`` (lines) on a translucent band in the top-left corner."""
    from PIL import Image, ImageDraw

    picture = Image.fromarray(image)
    draw = ImageDraw.Draw(picture, "RGBA")
    font = _font(max(12, image.shape[0] // 26))
    box = draw.multiline_textbbox((10, 8), text, font=font, spacing=4)
    draw.rectangle((box[0] - 6, box[1] - 4, box[2] + 6, box[3] + 6), fill=(0, 0, 0, 140))
    draw.multiline_text((10, 8), text, font=font, fill=(255, 255, 255, 255), spacing=4)
    return np.asarray(picture)


@lru_cache(maxsize=4)
def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow without scalable default font
        return ImageFont.load_default()


def caption(robot: str, simulator: str, time: float, recovered_at: float | None) -> str:
    """The overlay text: robot and simulator, episode time [s], success state."""
    state = f"recovered at {recovered_at:.2f} s" if recovered_at is not None else "not recovered yet"
    return f"{robot} | {simulator}\nt = {time:4.2f} s | {state}"


VIDEO_SUFFIXES = (".gif", ".mp4")


def write_video(frames: list[np.ndarray], path: Path, fps: int) -> Path:
    """Write frames to ``path`` (.gif: one 128-colour palette; .mp4: H.264 through imageio-ffmpeg), through a
    temporary file in the same folder, so a failed write leaves an old file intact."""
    import imageio.v3 as iio

    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise FrbenchError(f"--out {path}: expected a .gif or .mp4 file")
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.stem}.partial{suffix}")
    try:
        if suffix == ".gif":
            _write_gif(frames, partial, fps)
        else:
            iio.imwrite(partial, np.stack(frames), fps=fps, codec="libx264", plugin="FFMPEG", pixelformat="yuv420p",
                        output_params=["-crf", "28"], macro_block_size=8)
        os.replace(partial, path)
    except Exception as exc:
        raise FrbenchError(f"--out {path}: cannot write the video ({exc})") from None
    finally:
        partial.unlink(missing_ok=True)
    return path


def write_png(image: np.ndarray, path: Path) -> Path:
    """Write an RGB image (H, W, 3) uint8 to ``path`` atomically, as a 256-colour PNG (a third of the bytes)."""
    import io

    from PIL import Image

    buffer = io.BytesIO()
    picture = Image.fromarray(image).quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    picture.save(buffer, format="PNG", optimize=True)
    return atomic_write_bytes(path, buffer.getvalue())


def _write_gif(frames: list[np.ndarray], path: Path, fps: int) -> None:
    """One palette for the whole clip (quantised from a few frames), no dithering: small files, no flicker."""
    from PIL import Image

    sample = np.concatenate([frames[i] for i in np.linspace(0, len(frames) - 1, min(6, len(frames))).astype(int)])
    palette = Image.fromarray(sample).quantize(colors=128, method=Image.Quantize.MEDIANCUT)
    images = [Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0)

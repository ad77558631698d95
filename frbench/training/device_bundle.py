"""A training env's CPU-made parts, saved for a machine without the CPU stack (a GPU machine): a device bundle.

`frbench.training.env.RecoveryTrainingEnv` is built from `frbench.training.parts.TrainingParts`: the batch's robots
(robot files, Pinocchio's masses), the terrain rasters, the curriculum's first state, the learner's joint frame,
the reward table with the URDF's velocity limits and the bank of settled starts (MuJoCo C). `build_bundle` makes
them with `build_parts` and the simulator's compiled world (`CompiledWorld`: the ``MjModel`` of the grid world
and the first robot, the variants' model fields, the link names); `save_bundle` writes them as a folder and
`load_bundle` + `bundle_parts` give the same parts back with nothing but mujoco, mujoco-warp and torch (no
Pinocchio, robot packages or PyBullet): the env built from them is the env built on the CPU, its generator at the
same state. The bundle needs ``start_bank`` > 0 (such a machine cannot draw fresh starts: they need the robot
files).

Folder layout: ``model.mjb`` (the ``MjModel``), ``arrays.npz`` (below), ``meta.json`` (`FORMAT`; the
`TrainEnvConfig`; the robots' specs as data; the link names; the joint frame; the resolved reward table; the
generators' states; the curriculum's state; the raster's tiles and floor; the head's standing height).

Arrays (N environments, K robot variants, T tiles, M bank entries):

* ``world/<field>`` (K, …): each model field in which the variants differ;
* ``robots/assignment`` (N,), ``robots/variant_friction``, ``robots/variant_payload`` (K,),
  ``robots/group_masses`` (K, G) [kg]; for humanoids ``head/origins``, ``head/axes``, ``head/joints`` (the chain);
* ``raster/centres`` (T, 2) [m], ``raster/heights`` (T, n, n) float32 [m];
* ``bank/state_<field>`` (M, ·) float32, ``bank/tile``, ``bank/variant`` (M,), ``bank/shape`` (K, T).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from frbench.io import atomic_write_bytes, atomic_write_text

FORMAT = "frbench-device-bundle-v2"
#: Settled starts per (tile, robot variant) when the config names none: the GPU run's 70 tiles x 32 morphologies
#: give 17,920.
STARTS_PER_CELL = 8


@dataclasses.dataclass
class DeviceBundle:
    """A bundle as data: ``model`` (``mujoco.MjModel``), ``arrays`` (name → numpy array), ``meta`` (JSON dict)."""

    model: object
    arrays: dict
    meta: dict

    @property
    def config(self):
        """The `TrainEnvConfig` the bundle was built for."""
        from frbench.training.config import TrainEnvConfig

        return TrainEnvConfig.from_dict(self.meta["config"])


# ---------------------------------------------------------------------------------------------- specs as data
def _spec_data(spec) -> dict:
    out = {}
    for f in dataclasses.fields(spec):
        value = getattr(spec, f.name)
        if f.name.endswith("_groups"):
            value = [[g.name, list(g.links)] for g in value]
        elif isinstance(value, Path):
            value = str(value)
        out[f.name] = value
    return out


def _spec_of(data: dict):
    from frbench.robots.spec import LinkGroup, RobotSpec

    def tuples(value):
        return tuple(tuples(v) for v in value) if isinstance(value, list) else value

    fields = {}
    for name, value in data.items():
        if name.endswith("_groups"):
            value = tuple(LinkGroup(g, tuple(links)) for g, links in value)
        elif name == "urdf_path":
            value = Path(value)
        else:
            value = tuples(value)
        fields[name] = value
    return RobotSpec(**fields)


def _rng_state(rng: np.random.Generator) -> dict:
    return rng.bit_generator.state


def _rng_of(state: dict) -> np.random.Generator:
    rng = np.random.Generator(getattr(np.random, state["bit_generator"])())
    rng.bit_generator.state = state
    return rng


# ---------------------------------------------------------------------------------------------- build, save, load
def build_bundle(cfg, log=print) -> DeviceBundle:
    """The bundle of `TrainEnvConfig` ``cfg`` (module docstring); needs the CPU stack, and a ValueError when ``cfg``
    has no ``start_bank`` (`STARTS_PER_CELL` is the GPU run's)."""
    from frbench.backends.mujoco_warp_backend import CompiledWorld
    from frbench.training.parts import build_parts

    if not cfg.start_bank:
        raise ValueError(f"start_bank 0: a device bundle needs settled starts (e.g. --set start_bank="
                         f"{STARTS_PER_CELL}); the machine it goes to cannot draw fresh ones")
    parts = build_parts(cfg, log=log)
    robots, raster = parts.robots, parts.raster
    world = CompiledWorld.of(robots.spec, parts.grid.world, robots.variants)
    arrays = {f"world/{k}": v for k, v in world.fields.items()}
    arrays.update({"robots/assignment": robots.assignment, "robots/variant_friction": robots.variant_friction,
                   "robots/variant_payload": robots.variant_payload, "robots/group_masses": robots.group_masses,
                   "robots/scales": robots.scales,
                   "raster/centres": raster.centres, "raster/heights": np.asarray(raster.heights, dtype=np.float32)})
    bank = parts.bank.to_arrays()
    bank.update({k: v.astype(np.float32) for k, v in bank.items() if k.startswith("state_")})
    arrays.update({f"bank/{k}": v for k, v in bank.items()})
    meta = {"format": FORMAT, "config": cfg.to_dict(), "specs": [_spec_data(s) for s in robots.specs],
            "link_names": list(world.link_names), "reward": _reward_data(parts.reward),
            "frame": _frame_data(parts.frame),
            "rng": _rng_state(parts.rng),
            "robots_rng": None if robots.rng is parts.rng else _rng_state(robots.rng),
            "curriculum": parts.curriculum.state_dict(),
            "raster": {"tile_keys": [list(k) for k in raster.tile_keys], "floor": raster.floor}}
    if robots.head is not None:
        arrays.update({f"head/{k}": v for k, v in robots.head.to_arrays().items()})
        meta["head_standing_height"] = robots.head.standing_height
    return DeviceBundle(world.model, arrays, meta)


def _frame_data(frame):
    """The learner's joint frame as JSON: None, a `JointFrame`'s fields, or a `BatchJointFrame`'s frames (its
    assignment is the robots', saved with them)."""
    if frame is None:
        return None
    if hasattr(frame, "assignment"):
        return {"batch": True, "frames": frame.to_dict()["frames"]}
    return dataclasses.asdict(frame)


def _frame_of(data, assignment):
    """The joint frame `_frame_data` wrote, for environments of robot ``assignment`` (N,)."""
    from frbench.robots.batch_frame import BatchJointFrame
    from frbench.robots.joint_frame import JointFrame

    if data is None:
        return None
    if data.get("batch"):
        return BatchJointFrame.from_dict({"frames": data["frames"], "assignment": [int(k) for k in assignment]})
    return JointFrame(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in data.items()})


def _reward_data(reward) -> dict:
    data = dataclasses.asdict(reward)
    data["weights"], data["overrides_reason"] = dict(reward.weights), dict(reward.overrides_reason)
    if isinstance(data["velocity_threshold"], tuple):
        data["velocity_threshold"] = list(data["velocity_threshold"])
    return data


def bundle_parts(bundle: DeviceBundle):
    """The `TrainingParts` saved in ``bundle`` (its generators at their saved states), without the CPU stack."""
    from frbench.backends.mujoco_warp_backend import CompiledWorld
    from frbench.training.curriculum import TerrainCurriculum
    from frbench.training.height_raster import HeightRaster
    from frbench.training.parts import TrainingParts
    from frbench.training.population import TrainingRobots
    from frbench.training.rewards import RewardConfig
    from frbench.training.start_bank import StartBank
    from frbench.training.step_reward import HeadPoints
    from frbench.training.terrain_grid import build_grid

    cfg, meta, a = bundle.config, bundle.meta, bundle.arrays
    rng = _rng_of(meta["rng"])
    robots_rng = rng if meta["robots_rng"] is None else _rng_of(meta["robots_rng"])
    specs = [_spec_of(s) for s in meta["specs"]]
    assignment = np.asarray(a["robots/assignment"])
    head = None
    if "head/origins" in a:
        head = HeadPoints.from_arrays(a["head/origins"], a["head/axes"], a["head/joints"], assignment,
                                      meta["head_standing_height"])
    robots = TrainingRobots(cfg, robots_rng, specs, assignment, a["robots/variant_friction"],
                            a["robots/variant_payload"], a["robots/group_masses"], head, a.get("robots/scales"))
    curriculum = TerrainCurriculum(cfg.num_envs, np.random.default_rng(0), families=cfg.families,
                                   start_level=cfg.start_level)
    curriculum.load_state_dict(meta["curriculum"])
    raster = HeightRaster.from_arrays(meta["raster"]["tile_keys"], a["raster/centres"], a["raster/heights"],
                                      meta["raster"]["floor"])
    reward = dict(meta["reward"])
    if isinstance(reward["velocity_threshold"], list):
        reward["velocity_threshold"] = tuple(reward["velocity_threshold"])
    frame = _frame_of(meta["frame"], assignment)
    bank = StartBank.from_arrays({k[len("bank/"):]: v for k, v in a.items() if k.startswith("bank/")})
    world = CompiledWorld(bundle.model, {k[len("world/"):]: v for k, v in a.items() if k.startswith("world/")},
                          tuple(meta["link_names"]))
    return TrainingParts(rng, build_grid(cfg.families), robots, curriculum, raster, frame, RewardConfig(**reward),
                         bank, world)


def save_bundle(bundle: DeviceBundle, folder) -> Path:
    """Write ``bundle`` to ``folder`` (model.mjb, arrays.npz, meta.json; each atomically)."""
    import io

    import mujoco

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    buffer = np.zeros(mujoco.mj_sizeModel(bundle.model), dtype=np.uint8)
    mujoco.mj_saveModel(bundle.model, None, buffer)
    atomic_write_bytes(folder / "model.mjb", buffer.tobytes())
    data = io.BytesIO()
    np.savez_compressed(data, **{name.replace("/", "__"): value for name, value in bundle.arrays.items()})
    atomic_write_bytes(folder / "arrays.npz", data.getvalue())
    atomic_write_text(folder / "meta.json", json.dumps(bundle.meta, indent=1) + "\n")
    return folder


def load_bundle(folder) -> DeviceBundle:
    """A bundle written by `save_bundle` (needs mujoco, not Pinocchio or the robot packages)."""
    import mujoco

    from frbench.errors import FrbenchError

    folder = Path(folder)
    missing = [name for name in ("model.mjb", "arrays.npz", "meta.json") if not (folder / name).is_file()]
    if missing:
        raise FrbenchError(f"{folder}: not a device bundle (missing {', '.join(missing)})")
    meta = json.loads((folder / "meta.json").read_text())
    if meta.get("format") != FORMAT:
        raise FrbenchError(f"{folder / 'meta.json'}: format {meta.get('format')!r}, expected {FORMAT!r} "
                           "(build it again with tools/gpu_run/make_bundle.py)")
    model = mujoco.MjModel.from_binary_path(str(folder / "model.mjb"))
    with np.load(folder / "arrays.npz") as data:
        arrays = {name.replace("__", "/"): data[name] for name in data.files}
    return DeviceBundle(model, arrays, meta)


def check_bundle_config(bundle: DeviceBundle, cfg, folder) -> None:
    """A `FrbenchError` naming the first config field in which ``bundle`` (loaded from ``folder``) was built for
    another run than ``cfg``'s."""
    from frbench.errors import FrbenchError

    built, wanted = bundle.meta["config"], cfg.to_dict()
    differ = sorted(k for k in set(built) | set(wanted) if built.get(k) != wanted.get(k))
    if differ:
        field = differ[0]
        raise FrbenchError(f"{folder}/meta.json: config field {field} is {built.get(field)!r}, the run's "
                           f"{wanted.get(field)!r}; build the bundle with the run's flags")


def resized(bundle: DeviceBundle, num_envs: int) -> DeviceBundle:
    """``bundle`` for ``num_envs`` environments: its per-environment rows (robot variant, curriculum family, level
    and block) repeated in order, the config's ``num_envs`` changed; robots, world, rasters and bank shared. One
    bundle serves a throughput sweep over batch sizes."""
    n0 = len(bundle.arrays["robots/assignment"])
    rows = np.arange(int(num_envs)) % n0
    arrays = {**bundle.arrays, "robots/assignment": bundle.arrays["robots/assignment"][rows]}
    curriculum = dict(bundle.meta["curriculum"])
    for key in ("family", "level", "successes", "episodes"):
        curriculum[key] = [curriculum[key][i] for i in rows]
    meta = {**bundle.meta, "config": {**bundle.meta["config"], "num_envs": int(num_envs)}, "curriculum": curriculum}
    return DeviceBundle(bundle.model, arrays, meta)

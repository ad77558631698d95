"""What the device trainer needs from the CPU, built once: the compiled world, the batch's robots and a bank of
settled fallen starts (`build_bundle`), saved as a folder (`save_bundle` / `load_bundle`).

The device trainer (`frbench.training.device_env.DeviceTrainingEnv`) runs every step on the device; what only
the CPU tools can make — the MuJoCo model of the terrain grid (`frbench.backends.mujoco_model.build_model`),
sampled morphologies (URDFs, Pinocchio masses), the terrain rasters and settled fallen starts (the protocol's
draw, settled and screened by the episode engine in MuJoCo C) — is made here, the same way the CPU trainer
makes it (`frbench.training.env.RecoveryTrainingEnv`: the same generator draws in the same order, so a config
and seed give the same robots, families and levels). A saved bundle needs neither Pinocchio nor the robot
packages: a GPU machine with only mujoco, mujoco-warp and torch loads it.

Folder layout: ``model.mjb`` (the ``MjModel`` of the grid world and the first robot), ``arrays.npz`` (below),
``meta.json`` (the `TrainEnvConfig`, the resolved reward table, the robot's joint names, limits and kind, sizes,
and with randomisation the ranges each episode's physics is drawn from).

Arrays (N environments, K robot variants, T terrain tiles, M bank entries, J joints):

* ``variant/<field>`` (K, …): each MuJoCo model field in which the variants differ (`variant_fields`), and
  ``assignment`` (N,) each environment's variant; every world's model gets its variant's value;
* ``gainprm``, ``biasprm`` (N, nu, 10), ``forcerange`` (N, nu, 2): the actuators of each environment's first
  episode (gains, motor strength, motor friction; the CPU trainer's draw; later episodes redraw on the device);
  ``kp``, ``kd``, ``motor_strength``, ``motor_friction`` (N, J), ``friction``, ``payload`` (N,): the same physics
  (the critic reads them);
* ``masses`` (N, G) [kg], ``nominal_height`` (N,) [m], ``family``, ``level`` (N,): the estimator's mass labels,
  standing heights, each environment's curriculum family and first level;
* ``tile_of_cell`` (F, L + 1): the raster row of (family, level); ``heights`` (T, n, n) float32 [m],
  ``centres`` (T, 2) [m]: the terrain rasters (`height_raster.HeightRaster`);
* bank: ``bank_qpos`` (M, nq), ``bank_qvel`` (M, nv) float32 (positions on their tile in world coordinates),
  ``bank_tile`` (M,), ``bank_variant`` (M,);
* layout: ``qadr``, ``dadr`` (J,), ``link_body`` (links,), ``membership`` (links, C) bool, ``feet`` (F,),
  ``non_foot``, ``knees`` (knee groups, links per group), ``terrain_geoms``; for humanoids ``head_body``.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from frbench.io import atomic_write_bytes, atomic_write_text

#: Settled starts recorded per (tile, robot variant) unless told otherwise: the GPU run's 70 tiles x 32 morphologies
#: give 17,920 (2.6 MB); every episode of an environment starts from one of its cell's 8.
STARTS_PER_CELL = 8
#: Largest batch of simultaneous simulations the bank is settled in (MuJoCo C on the CPU).
BANK_BATCH = 128
FORMAT = "frbench-device-bundle-v1"


@dataclasses.dataclass
class DeviceBundle:
    """A loaded bundle: ``model`` (``mujoco.MjModel``), ``arrays`` (name → numpy array), ``meta`` (JSON dict)."""

    model: object
    arrays: dict
    meta: dict

    @property
    def config(self):
        """The `TrainEnvConfig` the bundle was built for."""
        from frbench.training.config import TrainEnvConfig

        return TrainEnvConfig.from_dict(self.meta["config"])

    @property
    def reward(self):
        """The resolved reward table (`rewards.RewardConfig`, velocity thresholds from the URDF)."""
        from frbench.training.rewards import RewardConfig

        data = dict(self.meta["reward"])
        if isinstance(data["velocity_threshold"], list):
            data["velocity_threshold"] = tuple(data["velocity_threshold"])
        return RewardConfig(**data)


def _reward_dict(reward) -> dict:
    return {"weights": dict(reward.weights), "epsilon": reward.epsilon,
            "velocity_threshold": (list(reward.velocity_threshold) if isinstance(reward.velocity_threshold, tuple)
                                   else reward.velocity_threshold),
            "posture_sigma2": reward.posture_sigma2, "scale_by_dt": reward.scale_by_dt,
            "overrides_reason": dict(reward.overrides_reason)}


def check_device_config(cfg) -> None:
    """Raise ``ValueError`` naming the first setting of ``cfg`` (a `TrainEnvConfig`) the device trainer lacks."""
    unsupported = {"base_controller": cfg.base_controller, "long_history": cfg.long_history,
                   "action_hold": cfg.action_hold != 1, "assist_force": cfg.assist_force,
                   "demo_start_fraction": cfg.demo_start_fraction, "rise_start_fraction": cfg.rise_start_fraction}
    for name, value in unsupported.items():
        if value:
            raise ValueError(f"{name}={getattr(cfg, name)!r} is a CPU-trainer setting; the device trainer runs "
                             "q* = q̊ + scale·a every control step from bank starts (set it to its default)")


def build_bundle(cfg, starts_per_cell: int = STARTS_PER_CELL, log=print) -> DeviceBundle:
    """The bundle of `TrainEnvConfig` ``cfg`` (module docstring); ``starts_per_cell`` settled starts per (tile,
    variant). Needs the CPU stack (MuJoCo C, Pinocchio, the robot files)."""
    import mujoco

    from frbench.backends.contact_layout import contact_layout
    from frbench.backends.mujoco_backend import variant_fields, variant_models, write_actuator_params
    from frbench.backends.mujoco_model import build_model, joint_addresses
    from frbench.backends.warp_model import buffer_sizes
    from frbench.robots.sim_urdf import sim_robot_file
    from frbench.training.curriculum import TerrainCurriculum
    from frbench.training.height_raster import HeightRaster
    from frbench.training.population import TrainingRobots
    from frbench.training.reward_tables import with_joint_velocity_limits
    from frbench.training.terrain_grid import build_grid

    check_device_config(cfg)
    # the CPU trainer's draws, in its order (`RecoveryTrainingEnv.__init__`)
    rng = np.random.default_rng(cfg.seed)
    grid = build_grid(cfg.families)
    robots = TrainingRobots.drawn(cfg, rng)
    spec, n = robots.spec, cfg.num_envs
    curriculum = TerrainCurriculum(n, rng, families=cfg.families, start_level=cfg.start_level)
    if not cfg.curriculum:
        curriculum.level[:] = rng.integers(1, 11, size=n)
    raster = HeightRaster(grid, sorted(grid.tiles))
    model = build_model(spec, grid.world)
    k = len(robots.specs)
    variants = robots.variants
    arrays: dict[str, np.ndarray] = {}
    if variants is not None:
        fields = variant_fields(model, variant_models(grid.world, variants), np.arange(k), lambda name: True)
        arrays.update({f"variant/{name}": value for name, value in fields.items()})
        arrays["assignment"] = np.asarray(robots.assignment, dtype=np.int64)
    else:
        arrays["assignment"] = np.zeros(n, dtype=np.int64)
    params = robots.episode_params()
    gain = np.repeat(model.actuator_gainprm[None], n, axis=0)
    bias = np.repeat(model.actuator_biasprm[None], n, axis=0)
    force_range = np.repeat(model.actuator_forcerange[None], n, axis=0)
    write_actuator_params(gain, bias, force_range, params, np.asarray(spec.torque_limits))
    motor_friction = np.zeros_like(params.kp) if params.motor_friction is None else params.motor_friction
    arrays.update(gainprm=gain, biasprm=bias, forcerange=force_range, kp=params.kp, kd=params.kd,
                  motor_strength=params.motor_strength, motor_friction=motor_friction, friction=np.asarray(params.friction, dtype=float),
                  payload=np.zeros(n) if params.payload is None else np.asarray(params.payload, dtype=float),
                  masses=robots.env_masses, nominal_height=np.asarray(robots.nominal_height, dtype=float),
                  family=curriculum.family.copy(), level=curriculum.level.copy())
    tiles = sorted(grid.tiles)
    tile_of_cell = np.full((len(cfg.families), 11), -1, dtype=np.int64)
    for (f, level), row in raster.index.items():
        tile_of_cell[f, level] = row
    arrays.update(tile_of_cell=tile_of_cell, heights=np.asarray(raster.heights, dtype=np.float32),
                  centres=raster.centres)
    # the bank: every tile, every variant ``starts_per_cell`` times, settled and screened by the engine
    qadr, dadr = joint_addresses(model, spec)
    log(f"bank: {len(tiles)} tiles x {k} variants x {starts_per_cell} settled starts (MuJoCo C)")
    arrays.update(_settled_bank(cfg, grid, raster, robots, tiles, starts_per_cell, model, qadr, dadr, rng))
    link_names = sim_robot_file(spec).links
    layout = contact_layout(link_names, spec.contact_groups, spec.knee_groups, spec.foot_links)
    knees = [np.asarray(g) for g in layout.knee_groups]
    if len({len(g) for g in knees}) > 1:
        raise ValueError(f"{spec.name}: knee groups of different sizes; the device trainer needs equal ones")
    arrays.update(qadr=qadr, dadr=dadr, link_body=np.array([model.body(name).id for name in link_names]),
                  membership=layout.membership, feet=np.arange(len(link_names))[layout.feet],
                  non_foot=np.arange(len(link_names))[layout.non_foot],
                  knees=np.stack(knees) if knees else np.zeros((0, 0), dtype=np.int64),
                  terrain_geoms=np.array([g for g in range(model.ngeom) if model.geom_bodyid[g] == 0]))
    meta = {"format": FORMAT, "config": cfg.to_dict(),
            "reward": _reward_dict(with_joint_velocity_limits(cfg.reward, spec.urdf_path, spec.joint_names)),
            "robot": {"name": spec.name, "kind": spec.kind, "joint_names": list(spec.joint_names),
                      "default_pose": list(map(float, spec.default_pose)),
                      "joint_lower": list(map(float, spec.joint_lower)),
                      "joint_upper": list(map(float, spec.joint_upper)),
                      "contact_groups": [g.name for g in spec.contact_groups]},
            "buffers": dict(zip(("nconmax", "njmax"), buffer_sizes(model))),
            "floor": float(raster.floor), "root_body": int(model.body(link_names[0]).id)}
    if cfg.randomize:  # the CPU trainer's per-episode draw (`TrainingRobots.episode_params`), redrawn on the device
        from frbench.backends.base import MOTOR_FRICTION_VELOCITY
        from frbench.training.population import NAMED_ROBOT_GAIN_FACTORS
        from frbench.training.randomization import CONTROL_RANGES

        ranges = {**CONTROL_RANGES, **cfg.gain_ranges}
        meta["physics"] = {
            "named": bool(cfg.robot), "kp": ranges.get("kp"), "kd": ranges.get("kd"),
            "gain_factors": NAMED_ROBOT_GAIN_FACTORS, "motor_strength": ranges.get("motor_strength"),
            "motor_friction": CONTROL_RANGES["motor_friction"], "nominal_kp": list(map(float, spec.kp)),
            "nominal_kd": list(map(float, spec.kd)), "torque_limits": list(map(float, spec.torque_limits)),
            "motor_friction_velocity": MOTOR_FRICTION_VELOCITY}
    if robots.head is not None:
        from frbench.training.step_reward import HEAD_FRAME

        meta["head"] = {"body": int(model.body(HEAD_FRAME).id), "standing_height": robots.head.standing_height}
    del mujoco
    return DeviceBundle(model, arrays, meta)


def _settled_bank(cfg, grid, raster, robots, tiles, per_cell, model, qadr, dadr, rng) -> dict[str, np.ndarray]:
    """Settled fallen starts of every variant on every tile: the protocol's draw moved to the tile, settled for
    ``cfg.settle_steps`` and screened (`CoreEnv.reset`), in batches of at most `BANK_BATCH` simulations."""
    from frbench.tasks.actions import DirectTargets
    from frbench.tasks.core_env import CoreEnv
    from frbench.training.action_hold import HeldAction

    k = len(robots.specs)
    per_batch = max(1, min(per_cell, BANK_BATCH // k)) if k <= BANK_BATCH else 1
    batch_variants = np.tile(np.arange(k), per_batch)
    b = len(batch_variants)
    variants = None if robots.variants is None else (robots.specs, batch_variants, robots.variant_friction,
                                                     robots.variant_payload)
    core = CoreEnv(robots.spec, "mujoco", grid.world, b, transform=DirectTargets(robots.spec.default_pose, 1.0),
                   hold=HeldAction(1), rng=rng, variants=variants, surface_rules=False, track_metrics=False)
    qpos, qvel, tile_rows, variant_ids = [], [], [], []
    try:
        rounds = -(-per_cell // per_batch)
        for tile in tiles:
            for _ in range(rounds):
                starts = core.draw_fallen(rng, [grid.tiles[tile]] * b, [grid.offsets[tile]] * b,
                                          [robots.specs[v] for v in batch_variants])
                core.reset(starts, None, cfg.settle_steps)
                s, ok = core.state, ~core.task.settle_diverged
                rows_q = np.tile(model.qpos0, (b, 1))
                rows_v = np.zeros((b, model.nv))
                rows_q[:, 0:3], rows_q[:, 3:7], rows_q[:, qadr] = s.base_pos, s.base_quat, s.q
                rows_v[:, 0:3], rows_v[:, 3:6], rows_v[:, dadr] = s.base_linvel, s.base_angvel, s.qd
                qpos.append(rows_q[ok])
                qvel.append(rows_v[ok])
                tile_rows.append(np.full(int(ok.sum()), raster.index[tile]))
                variant_ids.append(batch_variants[ok])
    finally:
        core.close()
    return {"bank_qpos": np.concatenate(qpos).astype(np.float32), "bank_qvel": np.concatenate(qvel).astype(np.float32),
            "bank_tile": np.concatenate(tile_rows).astype(np.int64),
            "bank_variant": np.concatenate(variant_ids).astype(np.int64)}


def save_bundle(bundle: DeviceBundle, folder) -> Path:
    """Write ``bundle`` to ``folder`` (model.mjb, arrays.npz, meta.json; each atomically)."""
    import io

    import mujoco

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    size = mujoco.mj_sizeModel(bundle.model)
    buffer = np.zeros(size, dtype=np.uint8)
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
        raise FrbenchError(f"{folder / 'meta.json'}: format {meta.get('format')!r}, expected {FORMAT!r}")
    model = mujoco.MjModel.from_binary_path(str(folder / "model.mjb"))
    with np.load(folder / "arrays.npz") as data:
        arrays = {name.replace("__", "/"): data[name] for name in data.files}
    return DeviceBundle(model, arrays, meta)


#: The arrays with one row per environment (`resized` repeats them).
PER_ENV = ("assignment", "gainprm", "biasprm", "forcerange", "kp", "kd", "motor_strength", "motor_friction",
           "friction", "payload", "masses", "nominal_height", "family", "level")


def resized(bundle: DeviceBundle, num_envs: int) -> DeviceBundle:
    """``bundle`` for ``num_envs`` environments: its per-environment rows (`PER_ENV`: robot variant, physics,
    labels, family and level) repeated in order, the config's ``num_envs`` changed; the world, rasters and bank
    shared. One bundle serves a throughput sweep over batch sizes."""
    n0 = len(bundle.arrays["assignment"])
    rows = np.arange(int(num_envs)) % n0
    arrays = {k: (v[rows] if k in PER_ENV else v) for k, v in bundle.arrays.items()}
    meta = {**bundle.meta, "config": {**bundle.meta["config"], "num_envs": int(num_envs)}}
    return DeviceBundle(bundle.model, arrays, meta)

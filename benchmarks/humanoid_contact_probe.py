"""Where the violent contacts of the humanoids' episodes come from: start draw, contacts, PD step, planning model.

For each robot (default g1, icub, talos), MuJoCo, flat level 1, seed 0, episodes 0 … ``--episodes``−1:

* **robot**: mass [kg], weight [N], physics step; the stiffest PD mode at the default pose,
  b = max eig(M⁻¹Kp)·dt² and a = max eig(M⁻¹Kd)·dt, at the physics step and at the planner's
  ``planning_dt`` (explicit PD: stable while b + 2a < 4; the planner's ``implicitfast`` at a coarser step
  takes the damping implicitly: stable while b < 4 + 2a, one joint at a time);
* **start draw** (`frbench.tasks.initial_states.draw_start`: joint angles uniform within the limits,
  redrawn while two links overlap, at most `MAX_REDRAWS` times, then the last draw is kept): the fraction
  of ``--draws`` uniform joint draws whose links overlap (`self_intersects`), and the chance that all
  `MAX_REDRAWS` + 1 draws of a start overlap;
* **per episode**, the protocol's start (drawn, settled and screened by `RecoveryTask.reset`, as
  ``frbench evaluate`` runs it), replayed on one ``MjData`` of the same model (the settle, then the
  ``zero`` policy's default-pose hold for the episode's 5 s; this replay gives the evaluation's
  ``peak_contact_force`` of the ``zero`` policy): the overlapping link pairs (robot against robot) and the
  deepest overlap [m] at the draw, at t = 0 and at the end; the episode's peak non-foot contact force
  (read at each control step, as the metric does), over the weight, and how much of it comes from the
  robot's own links (self) rather than the ground;
* with ``--planner``: at each episode's t = 0, 32 planner candidates (the hold plan and perturbations of it, the
  planner's noise) rolled out over its horizon on the planning model at ``planning_dt`` and at the robot's own
  step (the acting simulator's physics): how many diverge on each, and how far apart the two end (mean |Δq|
  per joint, |Δz| of the root); ``--settings`` gives the planner's settings as ``$FRBENCH_MPC`` does.

``--redraws N`` sets `MAX_REDRAWS` for the run (the protocol's value is 50), to measure how a larger redraw
budget changes the starts; ``--policy mpc`` also runs that policy on the same episodes through the
evaluation's episode runner (``run_episodes``) and prints its successes and peak contact forces (slow:
about 2 min per iCub or Talos episode on 2 cores; the policy takes its settings from ``$FRBENCH_MPC``), with,
per episode, the fraction of (control step, joint) pairs whose applied torque is at its limit (≥ 98 %; all joints,
and the first 12, the legs), the root's height over the nominal height (the highest, the 10-90 % range from 1 s
on, the last) and the displacement from the start at the end; ``--trace S`` adds, every S seconds of each
episode, what the success test reads (root height over nominal, root and torso tilt, non-foot contact,
displacement).

Run: ``python benchmarks/humanoid_contact_probe.py`` (under a minute; ``--planner`` adds about 15 s);
``--robots icub --episodes 8``; ``--planner --redraws 2000``; ``--robots icub,talos --redraws 2000 --policy mpc``.
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np

from frbench.backends.base import RobotState
from frbench.backends.mujoco_model import build_model, joint_addresses
from frbench.backends.self_collision import self_intersects
from frbench.planning.config import PlannerConfig
from frbench.planning.cost import DIVERGED_COST
from frbench.planning.model import build_planning_model
from frbench.planning.sampler import Sampler
from frbench.policies.mpc import config_from_text
from frbench.robots.registry import get_robot
from frbench.robots.sim_urdf import sim_robot_file
from frbench.tasks import initial_states
from frbench.tasks.initial_states import SETTLE_GAIN_SCALE, draw_starts
from frbench.tasks.recovery import EPISODE_STEPS, SETTLE_STEPS, RecoveryTask, open_backend
from frbench.tasks.protocol import CONTROL_DT
from frbench.terrains import make_terrain

GRAVITY = 9.81


def pd_modes(spec, model) -> tuple[float, float]:
    """(max eig(M⁻¹Kp) [1/s²], max eig(M⁻¹Kd) [1/s]) at the default pose, root in the air."""
    data = mujoco.MjData(model)
    qadr, dadr = joint_addresses(model, spec)
    data.qpos[2] = spec.nominal_height + 1.0
    data.qpos[qadr] = spec.default_pose
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    rates = []
    for gains in (spec.kp, spec.kd):
        diagonal = np.zeros(model.nv)
        diagonal[dadr] = gains
        rates.append(float(np.max(np.linalg.eigvals(np.linalg.solve(mass, np.diag(diagonal))).real)))
    return rates[0], rates[1]


def overlap_fraction(spec, draws: int, seed: int = 0) -> float:
    """Fraction of uniform joint draws (within the limits) whose links overlap."""
    rng = np.random.default_rng(seed)
    lower, upper = np.asarray(spec.joint_lower), np.asarray(spec.joint_upper)
    return float(np.mean([self_intersects(spec, rng.uniform(lower, upper)) for _ in range(draws)]))


class Replay:
    """One MuJoCo simulation of the backend's model, stepped physics step by physics step."""

    def __init__(self, spec, terrain):
        self.spec, self.model = spec, build_model(spec, terrain)
        self.data = mujoco.MjData(self.model)
        self.qadr, self.dadr = joint_addresses(self.model, spec)
        feet = {self.model.body(f).id for f in spec.foot_links}
        self.bodies = [self.model.body(link).id for link in sim_robot_file(spec).links]
        self.non_foot = np.array([b for b in self.bodies if b not in feet])
        self.weight = float(self.model.body_subtreemass[self.bodies[0]]) * GRAVITY
        self.substeps = int(round(CONTROL_DT / self.model.opt.timestep))
        self.gain, self.bias = self.model.actuator_gainprm.copy(), self.model.actuator_biasprm.copy()

    def place(self, pos, quat, q) -> None:
        """The robot at rest at (pos, quat, q)."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[0:3], self.data.qpos[3:7], self.data.qpos[self.qadr] = pos, quat, q
        mujoco.mj_forward(self.model, self.data)

    def gains(self, scale: float) -> None:
        self.model.actuator_gainprm[:] = self.gain * scale
        self.model.actuator_biasprm[:] = self.bias * scale

    def control_step(self, targets) -> None:
        self.data.ctrl[: self.spec.n_joints] = targets
        mujoco.mj_step(self.model, self.data, nstep=self.substeps)

    def self_overlaps(self) -> tuple[set, float]:
        """(pairs of overlapping links of the robot, deepest overlap [m], 0 if none) at the current state."""
        model, data, pairs, deepest = self.model, self.data, set(), 0.0
        for i in range(data.ncon):
            contact = data.contact[i]
            a, b = model.geom_bodyid[contact.geom1], model.geom_bodyid[contact.geom2]
            if a and b and contact.dist < 0:
                pairs.add(tuple(sorted((model.body(a).name, model.body(b).name))))
                deepest = min(deepest, float(contact.dist))
        return pairs, deepest

    def peak_body_force(self) -> tuple[float, float]:
        """(largest net contact force on a non-foot link [N], the part of that link's contact forces that comes
        from the robot's own links [0-1])."""
        forces = np.linalg.norm(self.data.cfrc_ext[self.non_foot, 3:6], axis=1)
        k = int(np.argmax(forces))
        body, own, total, wrench = self.non_foot[k], 0.0, 0.0, np.zeros(6)
        for i in range(self.data.ncon):
            contact = self.data.contact[i]
            a, b = self.model.geom_bodyid[contact.geom1], self.model.geom_bodyid[contact.geom2]
            if body in (a, b):
                mujoco.mj_contactForce(self.model, self.data, i, wrench)
                f = float(np.linalg.norm(wrench[:3]))
                total += f
                own += f if (a and b) else 0.0
        return float(forces[k]), own / total if total > 0 else 0.0

    def state(self) -> RobotState:
        d = self.data
        return RobotState(base_pos=d.qpos[None, 0:3].copy(), base_quat=d.qpos[None, 3:7].copy(),
                          base_linvel=d.qvel[None, 0:3].copy(), base_angvel=d.qvel[None, 3:6].copy(),
                          q=d.qpos[None, self.qadr].copy(), qd=d.qvel[None, self.dadr].copy())


def screened_starts(spec, terrain, episodes: int):
    """The cell's starts as ``frbench evaluate`` runs them (drawn, settled, redrawn while upright)."""
    starts = draw_starts(spec, terrain, "flat", 1, 0, range(episodes))
    with open_backend("mujoco", spec, episodes, terrain) as backend:
        task = RecoveryTask(spec, backend, terrain, episodes)
        task.reset(starts)
        return task.starts


def planning_check(spec, terrain, state: RobotState, config: PlannerConfig) -> dict[str, float]:
    """One replanning's candidates from ``state`` rolled out on the planning model at ``planning_dt`` and at the
    robot's own step (the acting simulator's physics): how many diverge at each, and, over the candidates that
    diverge at neither, the mean |Δq| per joint [rad] and |Δz| of the root [m] between the two at the horizon's end."""
    models = [build_planning_model(spec, terrain, dt) for dt in (config.planning_dt, spec.physics_dt)]
    samplers = [Sampler(spec, planning, config) for planning in models]
    x0 = [p.initial_state(state, 0, mujoco.MjData(p.model)) for p in models]
    rng = np.random.default_rng(0)
    noise = rng.standard_normal((config.samples - 1, config.knots, spec.n_joints))
    nominal = samplers[0].hold(state.q[0])
    candidates = np.concatenate([nominal[None], np.clip(nominal + samplers[0].sigma * noise, samplers[0].lower,
                                                        samplers[0].upper)])
    costs, ends = [], []
    for sampler, x in zip(samplers, x0):
        costs.append(sampler.evaluate(x, candidates, 0.0, state.base_pos[0, :2]))
        ends.append(sampler._state[: len(candidates), -1].copy())
    ok = (costs[0] < DIVERGED_COST) & (costs[1] < DIVERGED_COST)
    qcols = 1 + models[0].qadr
    dq = np.abs(ends[0][ok][:, qcols] - ends[1][ok][:, qcols]).mean()
    dz = np.abs(ends[0][ok][:, 3] - ends[1][ok][:, 3]).mean()
    return {"diverged at planning_dt": int(np.sum(costs[0] >= DIVERGED_COST)),
            "diverged at own step": int(np.sum(costs[1] >= DIVERGED_COST)),
            "mean |dq| [rad]": round(float(dq), 3), "mean |dz| root [m]": round(float(dz), 3)}


def tilt_deg(gravity_z) -> np.ndarray:
    """Tilt from vertical [deg] of a frame whose projected gravity z is ``gravity_z`` (−1 upright)."""
    return np.degrees(np.arccos(np.clip(-np.asarray(gravity_z, dtype=float), -1.0, 1.0)))


def print_trace(trace: dict, e: int, every: int) -> None:
    """Episode ``e``'s success-test signals every ``every`` control steps: root height over nominal, root and torso
    tilt [deg], whether a non-foot link touches anything, displacement [m]."""
    print("        t [s]  height/nominal  root tilt  torso tilt  body contact  displacement")
    for k in range(every - 1, len(trace["height"]), every):
        torso = trace["torso_tilt"][k]
        print(f"        {(k + 1) * CONTROL_DT:5.2f}  {trace['height'][k][e]:14.2f}  {trace['root_tilt'][k][e]:9.0f}  "
              f"{'-' if torso is None else f'{torso[e]:.0f}':>10}  {bool(trace['body_contact'][k][e])!s:>12}  "
              f"{trace['displacement'][k][e]:12.2f}")


def probe(name: str, episodes: int, draws: int, planner: bool, policy: str | None, settings: str = "",
          trace_every: int = 0) -> None:
    spec = get_robot(name)
    terrain = make_terrain("flat", 1, 0)
    replay = Replay(spec, terrain)
    config, _ = config_from_text(settings)
    kp_rate, kd_rate = pd_modes(spec, replay.model)
    print(f"== {name}: {replay.weight / GRAVITY:.1f} kg, weight {replay.weight:.0f} N, physics step {spec.physics_dt * 1e3:g} ms")
    for label, dt in (("physics step", spec.physics_dt), ("planning_dt", config.planning_dt)):
        b, a = kp_rate * dt**2, kd_rate * dt
        print(f"   stiffest PD mode at the {label} ({dt * 1e3:g} ms): b = Kp dt²/I {b:.2f}, a = Kd dt/I {a:.2f}, "
              f"explicit b + 2a = {b + 2 * a:.2f} (stable < 4)")
    fraction = overlap_fraction(spec, draws)
    redraws = initial_states.MAX_REDRAWS
    print(f"   uniform joint draws with overlapping links: {fraction:.3f} of {draws}; chance that all "
          f"{redraws + 1} draws of a start overlap: {fraction ** (redraws + 1):.3g}")
    starts = screened_starts(spec, terrain, episodes)
    peaks = []
    for e in range(episodes):
        replay.place(starts.base_pos[e], starts.base_quat[e], starts.q[e])
        drawn = replay.self_overlaps()
        replay.gains(SETTLE_GAIN_SCALE)
        for _ in range(SETTLE_STEPS):
            replay.control_step(starts.q[e])
        replay.gains(1.0)
        start, state0 = replay.self_overlaps(), replay.state()
        peak, own = 0.0, 0.0
        for _ in range(EPISODE_STEPS):
            replay.control_step(spec.default_pose)
            force, share = replay.peak_body_force()
            if force > peak:
                peak, own = force, share
        end = replay.self_overlaps()
        peaks.append(peak)
        print(f"   ep {e} {starts.kinds[e]:<10} overlapping link pairs (deepest [m]): draw {len(drawn[0]):2d} "
              f"({drawn[1]:+.3f}), t=0 {len(start[0]):2d} ({start[1]:+.3f}), end {len(end[0]):2d} ({end[1]:+.3f}); "
              f"zero: peak contact {peak:8.0f} N = {peak / replay.weight:6.1f} x weight, {own:.0%} self")
        if start[0]:
            print(f"        at t=0: {', '.join('-'.join(p) for p in sorted(start[0])[:6])}")
        if planner:
            print(f"        {config.samples} planner candidates, planning_dt against own step: {planning_check(spec, terrain, state0, config)}")
    if policy:
        from frbench.evaluation.episodes import run_episodes
        from frbench.policies.registry import load_policy

        limits = np.asarray(spec.torque_limits)
        trace = {"saturated": [], "height": [], "displacement": [], "root_tilt": [], "torso_tilt": [],
                 "body_contact": []}

        def record(task, targets):
            signals = task.signals
            trace["saturated"].append(np.abs(task.state.tau) >= 0.98 * limits)
            trace["height"].append(np.asarray(signals.height) / spec.nominal_height)
            trace["displacement"].append(np.asarray(signals.displacement))
            trace["root_tilt"].append(tilt_deg(signals.gravity_z))
            trace["torso_tilt"].append(None if signals.torso_gravity_z is None else tilt_deg(signals.torso_gravity_z))
            trace["body_contact"].append(np.asarray(signals.body_contact))

        task = run_episodes(spec, "mujoco", terrain, screened_starts(spec, terrain, episodes), load_policy(policy),
                            on_step=record)
        metrics = task.metrics
        saturated, height, away = (np.asarray(trace[k]) for k in ("saturated", "height", "displacement"))
        for e in range(episodes):
            print(f"   {policy} ep {e}: success {bool(task.success.success[e])}, peak contact "
                  f"{metrics.peak_contact_force[e]:.0f} N = {metrics.peak_contact_force[e] / replay.weight:.1f} x weight, "
                  f"energy {metrics.energy[e]:.0f} J; torque-saturated joint-steps {saturated[:, e].mean():.3f} "
                  f"(legs {saturated[:, e, :12].mean():.3f}); root height / nominal: max {height[:, e].max():.2f}, "
                  f"at 1-5 s {np.percentile(height[50:, e], 10):.2f}-{np.percentile(height[50:, e], 90):.2f} (10-90 %), "
                  f"end {height[-1, e]:.2f}; displacement at the end {away[-1, e]:.2f} m")
            if trace_every:
                print_trace(trace, e, trace_every)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="g1,icub,talos")
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--draws", type=int, default=300, help="uniform joint draws for the overlap fraction")
    parser.add_argument("--redraws", type=int, default=None, help="MAX_REDRAWS for this run (protocol: 50)")
    parser.add_argument("--planner", action="store_true", help="compare the planning model at planning_dt with the robot's own step at t = 0")
    parser.add_argument("--policy", default=None, help="also run this policy on the episodes (e.g. mpc)")
    parser.add_argument("--settings", default="", help="planner settings for --planner, as $FRBENCH_MPC (field=value,...)")
    parser.add_argument("--trace", type=float, default=0.0,
                        help="with --policy: print each episode's success-test signals every this many seconds")
    args = parser.parse_args()
    if args.redraws is not None:
        initial_states.MAX_REDRAWS = args.redraws
    for name in args.robots.split(","):
        probe(name, args.episodes, args.draws, args.planner, args.policy, args.settings,
              int(round(args.trace / CONTROL_DT)))


if __name__ == "__main__":
    main()

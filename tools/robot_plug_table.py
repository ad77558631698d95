"""Regenerate the robot-plug table: `frbench robot check` on every legged URDF of the installed packages.

For each file: kind, mass, derived Kp/Kd (first leg's joints), physics step,
measured standing heights (MuJoCo / PyBullet), check result and time; for
humanoids the whole left leg's gains (pelvis to foot), the kinematic height and
the support margin (the tilt that carries the CoM to the edge of the feet,
`frbench.robot_checks.check.static_support`). Runs the checks one after the other in
this process (each with a cold cache, so the time includes the gain derivation
and the height measurement).

    PYTHONPATH=$PWD python tools/robot_plug_table.py quadrupeds --json /tmp/quadrupeds.json
    PYTHONPATH=$PWD python tools/robot_plug_table.py humanoids
    PYTHONPATH=$PWD python tools/robot_plug_table.py quadrupeds --only solo12
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

QUADRUPEDS = [
    "erd:a1_description/urdf/a1.urdf",
    "erd:anymal_b_simple_description/robots/anymal.urdf",
    "erd:anymal_c_simple_description/urdf/anymal.urdf",
    "erd:b1_description/urdf/b1.urdf",
    "erd:go1_description/urdf/go1.urdf",
    "erd:go2_description/urdf/go2.urdf",
    "erd:hyq_description/robots/hyq_no_sensors.urdf",
    "erd:laikago_description/urdf/laikago.urdf",
    "erd:solo_description/robots/solo12.urdf",
    "pb:a1/a1.urdf",
    "pb:aliengo/aliengo.urdf",
    "pb:laikago/laikago.urdf",
    "pb:laikago/laikago_toes.urdf",
    "pb:laikago/laikago_toes_limits.urdf",
    "pb:laikago/laikago_toes_zup.urdf",
    "pb:laikago/laikago_toes_zup_lores.urdf",
    "pb:mini_cheetah/mini_cheetah.urdf",
    "pb:quadruped/spirit40.urdf",
    "pb:quadruped/spirit40newer.urdf",
    "pb:quadruped/vision60.urdf",
]
HUMANOIDS = [
    "erd:g1_description/urdf/g1_29dof_rev_1_0.urdf",
    "erd:g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf",
    "erd:talos_data/robots/talos_reduced.urdf",
    "erd:talos_data/robots/talos_reduced_box.urdf",
    "erd:talos_data/robots/talos_reduced_corrected.urdf",
    "erd:talos_data/robots/talos_full_v2.urdf",
    "erd:talos_data/robots/talos_full_v2_box.urdf",
    "erd:romeo_description/urdf/romeo.urdf",
    "erd:romeo_description/urdf/romeo_small.urdf",
    "erd:romeo_description/urdf/romeo_laas_small.urdf",
    "erd:icub_description/robots/icub.urdf",
    "erd:icub_description/robots/icub_reduced.urdf",
    "erd:simple_humanoid_description/urdf/simple_humanoid.urdf",
    "erd:simple_humanoid_description/urdf/simple_humanoid_classical.urdf",
    "erd:human_description/robots/human.urdf",
    "erd:bolt_description/robots/bolt.urdf",
    "erd:alexander_description/urdf/alexander_v1.lowerBodyOnly.urdf",
]


def resolve(entry: str) -> str:
    """``erd:``/``pb:`` prefixed names to absolute paths."""
    from frbench.robots.paths import example_robot_data, pybullet_data_file

    prefix, _, rest = entry.partition(":")
    return str(example_robot_data(rest) if prefix == "erd" else pybullet_data_file(rest))


def check_one(entry: str, sidecar: str | None = None) -> dict:
    """One row: the check of ``entry`` (with ``sidecar`` if given), or the refusal."""
    from frbench.errors import FrbenchError
    from frbench.robots import ground_truth
    from frbench.robot_checks.check import check_robot
    from frbench.robot_checks.lookup import with_measured_height
    from frbench.robots.infer import spec_from_path

    row = {"file": entry}
    started = time.perf_counter()
    try:
        spec = with_measured_height(spec_from_path(resolve(entry), sidecar))
        report = check_robot(spec)
    except FrbenchError as exc:
        row.update(result="refused", message=str(exc).replace(resolve(entry), entry), seconds=time.perf_counter() - started)
        return row
    standing = {name: result["height"] for name, result in report.standing.items()}
    if report.support is not None:
        row["support_tilt"] = report.support["tilt_margin"]
    if spec.kind == "humanoid":
        left = json.loads(dict(spec.extra)["legs"])["left"]
        row["left_leg"] = {j: [spec.kp[spec.joint_names.index(j)], spec.kd[spec.joint_names.index(j)]] for j in left}
    row.update(
        kind=spec.kind, mass=ground_truth.total_mass(spec), dof=spec.n_joints, physics_dt=spec.physics_dt,
        kp=list(spec.kp), kd=list(spec.kd), kinematic_height=report.kinematic_height,
        nominal_height=spec.nominal_height, standing=standing, result="pass" if report.ok else "FAIL",
        message="; ".join(report.problems), seconds=time.perf_counter() - started,
    )
    return row


def markdown(rows: list[dict]) -> str:
    """The table as Markdown."""
    lines = [
        "| file | kind | mass [kg] | Kp hip/thigh/calf (first 3) | Kd | dt [s] | height MJ / PB [m] | result | time [s] | message |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["result"] == "refused":
            lines.append(f"| {r['file']} | | | | | | | refused | {r['seconds']:.1f} | {r['message']} |")
            continue
        kp = "/".join(f"{v:.3g}" for v in r["kp"][:3])
        kd = "/".join(f"{v:.3g}" for v in r["kd"][:3])
        heights = " / ".join(f"{h:.3f}" for h in r["standing"].values())
        lines.append(
            f"| {r['file']} | {r['kind']} | {r['mass']:.2f} | {kp} | {kd} | {r['physics_dt']:g} | {heights} | "
            f"{r['result']} | {r['seconds']:.1f} | {r['message']} |"
        )
    return "\n".join(lines)


def humanoid_markdown(rows: list[dict]) -> str:
    """The humanoid table as Markdown: the left leg's gains from the pelvis to the foot."""
    lines = [
        "| file | mass [kg] | dof | Kp left leg, pelvis → foot [N·m/rad] | Kd [N·m·s/rad] | dt [s] | "
        "height kinematic / MJ / PB [m] | support tilt [rad] | result | time [s] | message |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["result"] == "refused":
            lines.append(f"| {r['file']} | | | | | | | | refused | {r['seconds']:.1f} | {r['message']} |")
            continue
        kp = "/".join(f"{v[0]:.3g}" for v in r["left_leg"].values())
        kd = "/".join(f"{v[1]:.3g}" for v in r["left_leg"].values())
        heights = " / ".join(f"{h:.3f}" for h in [r["kinematic_height"], *r["standing"].values()])
        lines.append(
            f"| {r['file']} | {r['mass']:.2f} | {r['dof']} | {kp} | {kd} | {r['physics_dt']:g} | {heights} | "
            f"{r.get('support_tilt', float('nan')):.3f} | {r['result']} | {r['seconds']:.1f} | {r['message']} |"
        )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("which", choices=("quadrupeds", "humanoids"))
    parser.add_argument("--only", default="", help="substring of the files to run")
    parser.add_argument("--json", default="", help="also write the rows here")
    args = parser.parse_args()
    entries = [e for e in (QUADRUPEDS if args.which == "quadrupeds" else HUMANOIDS) if args.only in e]
    os.environ["FRBENCH_CACHE"] = tempfile.mkdtemp(prefix="frbench-plug-table-")
    rows = []
    for entry in entries:
        rows.append(check_one(entry))
        print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
        if args.json:
            with open(args.json, "w") as handle:
                json.dump(rows, handle, indent=1)
    print(humanoid_markdown(rows) if args.which == "humanoids" else markdown(rows))
    passed = sum(r["result"] == "pass" for r in rows)
    print(f"\n{passed}/{len(rows)} pass")
    return 0


if __name__ == "__main__":
    sys.exit(main())

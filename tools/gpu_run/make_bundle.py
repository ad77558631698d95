"""Prepare, on the CPU, what the GPU run (tools/gpu_run/run.sh) needs besides the working tree.

    python tools/gpu_run/make_bundle.py [--out runs/gpu_payload] [--no-wheels] [--flags-file FILE]

Writes under ``--out`` (``runs/`` is git-ignored; the device tool carries it with ``carry``):

* ``go2/``: the device bundle of the training run (`frbench.training.device_bundle`: the training env's CPU-made
  parts — robots, rasters, curriculum, generators, the bank of settled starts — and the compiled world), built from
  the flags in tools/gpu_run/train_flags.txt (the same flags run.sh trains with, so the run's config and the
  bundle's agree); the GPU machine builds the one training env from it with neither Pinocchio nor the robot
  packages;
* ``g1/``: a G1 bundle (256 envs, 2 settled starts per tile) for the throughput sweep;
* ``wheels/``: the wheels the GPU machine lacks, for CPython 3.12 manylinux (``pip download --no-deps``), with
  warp-lang's 149 MB wheel split into parts of at most ``--part-mb`` MB (``warp_lang.whl.part-aa`` …), each sent
  by its own device call (docs/gpu.md).
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: The wheels the GPU machine lacks (it has torch, numpy, scipy, JAX, onnx with protobuf, matplotlib), pinned as
#: in requirements.lock: what ``frbench train --backend mujoco-warp`` imports there (measured with Pinocchio,
#: PyBullet and gymnasium blocked: mujoco and its glfw, Warp, rsl-rl with tensordict and GitPython, tensorboard
#: for the run's curve, tqdm, array-api-compat).
WHEELS = ("mujoco==4.0.0", "mujoco-core==4.0.0", "glfw==2.11.0", "mujoco-warp==4.0.0", "warp-lang==1.19.0",
          "rsl-rl-lib==5.5.1", "tensordict==0.15.3", "cloudpickle==3.1.2", "pyvers==0.2.3", "GitPython==3.2.1",
          "gitdb==4.0.12", "smmap==5.0.3", "tensorboard==2.21.0", "tqdm==4.70.1", "array-api-compat==1.16.0",
          "absl-py==2.5.1")


#: The GPU run's ``frbench train`` flags.
FLAGS_FILE = ROOT / "tools" / "gpu_run" / "train_flags.txt"


def train_flags(path: Path = FLAGS_FILE) -> list[str]:
    """The ``frbench train`` flags in ``path`` (default: the GPU run's, tools/gpu_run/train_flags.txt)."""
    return shlex.split(Path(path).read_text())


def training_config(path: Path = FLAGS_FILE):
    """The `TrainEnvConfig` that ``frbench train <the flags in path>`` builds."""
    from frbench.cli import build_parser
    from frbench.commands.train import morphology_range_changes, new_run_config, reward_weight_changes

    flags = train_flags(path)
    args = build_parser().parse_args(["train", *flags])
    weights = reward_weight_changes(args.motion_penalties, args.reward_weight)
    cfg, _ = new_run_config(args, "frbench train " + " ".join(flags), weights,
                            morphology_range_changes(args.morphology_range))
    return cfg


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "runs" / "gpu_payload")
    parser.add_argument("--no-wheels", action="store_true", help="bundles only")
    parser.add_argument("--part-mb", type=int, default=48)
    parser.add_argument("--flags-file", type=Path, default=FLAGS_FILE,
                        help="the training flags the Go2 bundle is built for (run.sh: TRAIN_FLAGS_FILE)")
    parser.add_argument("--g1-envs", type=int, default=256, help="environments of the G1 bundle (0: none)")
    parser.add_argument("--python-version", default="3.12", help="the wheels' CPython version")
    args = parser.parse_args(argv)
    from frbench.training.config import TrainEnvConfig
    from frbench.training.device_bundle import build_bundle, save_bundle

    cfg = training_config(args.flags_file)
    print(f"go2 bundle: {cfg.num_envs} envs, {cfg.num_morphologies} morphologies, {len(cfg.families)} families")
    save_bundle(build_bundle(cfg), args.out / "go2")
    if args.g1_envs:
        g1 = TrainEnvConfig(num_envs=args.g1_envs, robot="g1", backend="mujoco-warp", start_bank=2)
        save_bundle(build_bundle(g1), args.out / "g1")
    if not args.no_wheels:
        wheels = args.out / "wheels"
        wheels.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:",
                        "--python-version", args.python_version, "--platform", "manylinux_2_28_x86_64", "--dest", str(wheels),
                        *WHEELS], check=True)
        for wheel in wheels.glob("warp_lang-*.whl"):  # too large for one call: parts, joined on the GPU machine
            (wheels / "warp_lang.name").write_text(wheel.name + "\n")
            subprocess.run(["split", "-b", f"{args.part_mb}M", str(wheel), str(wheels / "warp_lang.whl.part-")],
                           check=True)
            wheel.unlink()
    for path in sorted(args.out.rglob("*")):
        if path.is_file():
            print(f"{path.stat().st_size / 2**20:8.1f} MiB  {path.relative_to(args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Where a result came from: versions, git commit, checksums of robots and checkpoints, the processor."""

from __future__ import annotations

import platform
import subprocess
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import frbench

_PACKAGES = {"mujoco": "mujoco", "pybullet": "pybullet", "pinocchio": "pin", "numpy": "numpy",
             "torch": "torch", "gymnasium": "gymnasium", "rsl_rl": "rsl-rl-lib", "example_robot_data": "example-robot-data",
             "mujoco_warp": "mujoco-warp", "warp": "warp-lang",  # the optional gpu extra
             "sapien": "sapien"}  # the optional physx extra (PhysX 5 inside)


def library_versions() -> dict[str, str]:
    """Python and the simulator/library versions."""
    out = {"python": platform.python_version()}
    for key, dist in _PACKAGES.items():
        try:
            out[key] = version(dist)
        except PackageNotFoundError:
            out[key] = "not installed"
    return out


def _git(*args: str) -> str | None:
    root = Path(frbench.__file__).resolve().parent.parent
    try:
        out = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def frbench_info() -> dict:
    """frbench's version, git commit (40 hex, or ``unknown`` outside a checkout) and whether the tree was modified."""
    commit = _git("rev-parse", "HEAD")
    dirty = _git("status", "--porcelain", "--untracked-files=no")
    return {"version": frbench.__version__, "git_commit": commit or "unknown", "git_dirty": bool(dirty)}


#: numpy's names (`numpy._core._multiarray_umath.__cpu_features__`) of the vector extensions recorded: those
#: that choose numpy's and OpenBLAS's kernels (x86-64, then Arm), in this order.
VECTOR_EXTENSIONS = ("SSE42", "AVX", "F16C", "FMA3", "AVX2", "AVX512F", "AVX512CD", "AVX512_SKX", "AVX512_CLX",
                     "AVX512_CNL", "AVX512_ICL", "AVX512_SPR", "ASIMD", "ASIMDHP", "ASIMDDP", "SVE")


def _cpuinfo() -> dict[str, str]:
    """The first processor's fields of Linux's /proc/cpuinfo ({} elsewhere)."""
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace")
    except OSError:
        return {}
    fields: dict[str, str] = {}
    for line in text.split("\n\n")[0].splitlines():
        key, _, value = line.partition(":")
        fields.setdefault(key.strip(), value.strip())
    return fields


def _clean(text: str, limit: int) -> str:
    """One line of printable text without markup, at most ``limit`` characters; ``unknown`` if empty."""
    text = " ".join("".join(ch for ch in text if ch.isprintable() and ch not in "<>").split())
    return text[:limit] or "unknown"


def processor_info() -> dict:
    """The processor this process runs on: ``vendor`` and ``model`` as the system names them (no host name),
    ``architecture`` (``x86_64``, ``aarch64``...) and ``vector_extensions``, the extensions of
    :data:`VECTOR_EXTENSIONS` numpy detects at run time. A record's episodes can depend on them: numpy's and
    its BLAS's kernels are chosen by them (docs/protocol.md)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # another numpy layout: the extensions are not known
        features = {}
    info = _cpuinfo()
    vendor = info.get("vendor_id") or info.get("CPU implementer") or ""
    model = info.get("model name") or info.get("Hardware") or platform.processor()
    return {
        "vendor": _clean(vendor, 64),
        "model": _clean(model, 128),
        "architecture": _clean(platform.machine(), 32),
        "vector_extensions": [name for name in VECTOR_EXTENSIONS if features.get(name)],
    }


def processor_label(processor: dict | None) -> str:
    """``AuthenticAMD AMD EPYC (x86_64; AVX2, AVX512F, ...)``, or ``not recorded``."""
    if not processor:
        return "not recorded"
    extensions = ", ".join(processor["vector_extensions"]) or "none detected"
    return f"{processor['vendor']} {processor['model']} ({processor['architecture']}; {extensions})"

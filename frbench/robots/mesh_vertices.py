"""Vertices of a robot's collision meshes, read without a mesh library: COLLADA (placed by its scene's node
matrices, unit and up axis), ASCII OBJ/STL and binary STL. The simulation URDF (`frbench.robots.sim_urdf`) fits
a primitive to each mesh's vertices. Shapes: (n, 3) [m].
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

_COLLADA_UP = {
    "Z_UP": np.eye(3),
    "Y_UP": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),  # +90° about x: y becomes z
    "X_UP": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),  # −90° about y: x becomes z
}


def collada_vertices(root) -> np.ndarray:
    """Vertices (n, 3) of a COLLADA document, placed by its scene's node matrices, unit and up axis.

    A document drawn y-up (``<up_axis>Y_UP``, iCub's collision meshes) is turned z-up, as the
    COLLADA specification asks of a consumer; without it iCub's feet lie across the leg.
    """
    local = lambda element: element.tag.rsplit("}", 1)[-1]  # noqa: E731
    geometries = {}
    for geometry in root.iter():
        if local(geometry) != "geometry":
            continue
        for array in geometry.iter():
            if local(array) == "float_array" and "position" in (array.get("id") or "").lower():
                geometries[geometry.get("id")] = np.array([float(v) for v in (array.text or "").split()]).reshape(-1, 3)
                break
    unit = next((float(e.get("meter", 1)) for e in root.iter() if local(e) == "unit"), 1.0)
    placed = []

    def visit(node, matrix):
        for child in node:
            tag = local(child)
            if tag == "matrix":
                matrix = matrix @ np.array([float(v) for v in child.text.split()]).reshape(4, 4)
            elif tag == "translate":
                step = np.eye(4)
                step[:3, 3] = [float(v) for v in child.text.split()]
                matrix = matrix @ step
            elif tag == "scale":
                matrix = matrix @ np.diag([*(float(v) for v in child.text.split()), 1.0])
        for child in node:
            if local(child) == "instance_geometry" and child.get("url", "").lstrip("#") in geometries:
                vertices = geometries[child.get("url").lstrip("#")]
                placed.append(vertices @ matrix[:3, :3].T + matrix[:3, 3])
            elif local(child) == "node":
                visit(child, matrix)

    for scene in root.iter():
        if local(scene) == "visual_scene":
            visit(scene, np.eye(4))
    vertices = np.vstack(placed) if placed else (np.vstack(list(geometries.values())) if geometries else np.zeros((0, 3)))
    up = next(((e.text or "").strip().upper() for e in root.iter() if local(e) == "up_axis"), "Z_UP")
    return (vertices @ _COLLADA_UP.get(up, np.eye(3)).T) * unit


def text_mesh_vertices(path: Path) -> np.ndarray | None:
    """Vertices (n, 3) of a mesh MuJoCo cannot decode (COLLADA ``.dae``, ASCII STL); None for other files."""
    import xml.etree.ElementTree as ET

    suffix = Path(path).suffix.lower()
    try:
        if suffix == ".dae":
            return collada_vertices(ET.parse(path).getroot())
        if suffix == ".stl":
            with open(path, "rb") as handle:
                head = handle.read(5)
            if head.lower() != b"solid":
                return None
            text = Path(path).read_text(encoding="utf-8", errors="replace")
            if "facet" not in text:
                return None
            rows = [line.split()[1:4] for line in text.splitlines() if line.strip().startswith("vertex")]
            return np.array(rows, dtype=float).reshape(-1, 3)
    except (OSError, ValueError, ET.ParseError):
        return np.zeros((0, 3))
    return None


def binary_stl_vertices(path: Path) -> np.ndarray | None:
    """Vertices (n, 3) of a binary STL file (80-byte header, triangle count, 50 bytes a triangle); None otherwise."""
    try:
        raw = Path(path).read_bytes()
    except OSError:
        return None
    if len(raw) < 84:
        return None
    count = int(np.frombuffer(raw, dtype="<u4", count=1, offset=80)[0])
    if count == 0 or len(raw) != 84 + 50 * count:
        return None
    rows = np.frombuffer(raw, dtype=np.uint8, offset=84).reshape(count, 50)[:, 12:48]
    return np.ascontiguousarray(rows).view("<f4").reshape(-1, 3).astype(float)

"""Triangle meshes from files: OBJ, OFF and STL read here, PLY through trimesh.

Every reader keeps the file's vertex numbering (per-vertex data must not shift): no vertex
is merged, dropped or reordered, except STL's, which stores each triangle's corners apart
and is welded by position (`weld`). NaN or infinite coordinates, indices outside the vertex list and
vertices no face uses are refused by `Mesh`'s checks, never repaired. Text is read as bytes
and decoded as Latin-1, so a stray non-ASCII byte in a comment or a name cannot fail the read;
every failure is one ValueError naming the file and what is wrong. This module knows nothing
of `Mesh`: `Mesh.from_file` (`_mesh`) builds the domain from the arrays it returns.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from .._checks import check_memory

FORMATS = ("obj", "ply", "stl", "off")
FILE_BYTES = 40  # memory a byte of a mesh file may cost once parsed (Python lists of floats), at most


class MeshFileError(ValueError):
    """What is wrong with a mesh file (a ValueError)."""


def read_mesh_file(path) -> dict:
    """{"vertices", "faces"[, "uv", "uv_faces"][, "welded"]} of the mesh in `path` (NumPy arrays)."""
    from .._files import check_regular_file

    path = Path(path)
    ext = path.suffix.lower().lstrip(".")
    if ext not in FORMATS:
        raise ValueError(f"Mesh.from_file: unknown format {path.suffix!r}; allowed: {', '.join(FORMATS)}")
    path = check_regular_file(path, "mesh")
    check_memory(path.stat().st_size * FILE_BYTES, f"reading the mesh {path}")
    try:
        data = {"obj": _read_obj, "off": _read_off, "stl": _read_stl, "ply": _read_ply}[ext](path)
    except MeshFileError as err:
        raise ValueError(f"Mesh.from_file: {path} is not a valid {ext.upper()} mesh ({err})") from None
    except (ValueError, IndexError, TypeError, OverflowError, UnicodeError, EOFError, struct.error, KeyError,
            AttributeError, MemoryError) as err:
        why = str(err).strip() or type(err).__name__
        raise ValueError(f"Mesh.from_file: {path} is not a valid {ext.upper()} mesh ({why})") from None
    if len(data["faces"]) == 0:
        raise ValueError(f"Mesh.from_file: {str(path)!r} holds no triangles")
    return data


def _number(text: str, what: str, line: int) -> float:
    try:
        return float(text)
    except ValueError:
        raise MeshFileError(f"line {line}: {what} {text!r} is not a number") from None


def _index(text: str, count: int, what: str, line: int) -> int:
    """A 1-based (or negative, from the end) OBJ index as a 0-based one."""
    try:
        i = int(text)
    except ValueError:
        raise MeshFileError(f"line {line}: {what} index {text!r} is not a whole number") from None
    if i == 0 or not -count <= i <= count:
        raise MeshFileError(f"line {line}: {what} index {i} is outside 1..{count}")
    return i - 1 if i > 0 else count + i


def _arrays(vertices, faces) -> dict:
    """{"vertices": (V, 3) float64, "faces": (F, 3) int64}, from lists or arrays (empty ones too)."""
    return {"vertices": np.asarray(vertices, np.float64).reshape(-1, 3), "faces": np.asarray(faces, np.int64).reshape(-1, 3)}


def _fan(corners):
    """A polygon's corners as triangles (a fan from the first corner, as trimesh splits quads)."""
    return [(corners[0], corners[k], corners[k + 1]) for k in range(1, len(corners) - 1)]


def _read_obj(path: Path) -> dict:
    vertices, uvs, faces, uv_faces, textured = [], [], [], [], True
    for n, raw in enumerate(path.read_bytes().decode("latin-1").splitlines(), 1):
        parts = raw.split("#", 1)[0].split()
        if not parts:
            continue
        kind, rest = parts[0], parts[1:]
        if kind == "v":
            if len(rest) < 3:
                raise MeshFileError(f"line {n}: a vertex needs 3 coordinates (got {len(rest)})")
            vertices.append([_number(t, "coordinate", n) for t in rest[:3]])
        elif kind == "vt":
            if not rest:
                raise MeshFileError(f"line {n}: a texture vertex needs coordinates")
            uvs.append([_number(t, "texture coordinate", n) for t in (rest + ["0"])[:2]])
        elif kind == "f":
            if len(rest) < 3:
                raise MeshFileError(f"line {n}: a face needs at least 3 corners (got {len(rest)})")
            corners, tcorners = [], []
            for token in rest:
                pieces = token.split("/")
                corners.append(_index(pieces[0], len(vertices), "vertex", n))
                if len(pieces) > 1 and pieces[1]:
                    tcorners.append(_index(pieces[1], len(uvs), "texture vertex", n))
            textured &= len(tcorners) == len(corners)
            faces += _fan(corners)
            if textured:
                uv_faces += _fan(tcorners)
    out = _arrays(vertices, faces)
    if textured and uvs and len(uv_faces) == len(faces):
        out["uv"], out["uv_faces"] = np.asarray(uvs, np.float64), np.asarray(uv_faces, np.int64)
    return out


def _read_off(path: Path) -> dict:
    tokens = []
    for raw in path.read_bytes().decode("latin-1").splitlines():
        tokens += raw.split("#", 1)[0].split()
    if not tokens or not tokens[0].upper().endswith("OFF"):
        raise MeshFileError("it does not start with OFF")
    head = tokens[0].upper()
    if head not in ("OFF", "COFF", "NOFF", "CNOFF", "STOFF"):
        raise MeshFileError(f"its header {tokens[0]!r} is not one this reader knows (OFF, COFF, NOFF, STOFF)")
    per_vertex = 3 + {"OFF": 0, "COFF": 4, "NOFF": 3, "CNOFF": 7, "STOFF": 2}[head]
    try:
        n_v, n_f = int(tokens[1]), int(tokens[2])
    except (IndexError, ValueError):
        raise MeshFileError("its counts line (vertices faces edges) is missing or not whole numbers") from None
    if n_v < 0 or n_f < 0:
        raise MeshFileError(f"its counts {n_v} vertices, {n_f} faces are negative")
    # each vertex or face takes at least a token: a count beyond the tokens is a lie, refused
    # before anything the counts size is built
    if n_v * per_vertex + n_f * 4 > len(tokens) - 4 + 1:
        raise MeshFileError(f"it declares {n_v} vertices and {n_f} faces but holds only {len(tokens)} numbers")
    at = 4 if len(tokens) > 3 else 3
    vertices = []
    for k in range(n_v):
        row = tokens[at:at + per_vertex]
        vertices.append([_number(t, "coordinate", k + 1) for t in row[:3]])
        at += per_vertex
    faces = []
    for k in range(n_f):
        if at >= len(tokens):
            raise MeshFileError(f"face {k} is missing")
        m = int(tokens[at])
        if m < 3 or at + 1 + m > len(tokens):
            raise MeshFileError(f"face {k} has {m} corners")
        corners = []
        for t in tokens[at + 1:at + 1 + m]:
            i = int(t)
            if not 0 <= i < n_v:
                raise MeshFileError(f"face {k} names vertex {i}, outside 0..{n_v - 1}")
            corners.append(i)
        faces += _fan(corners)
        at += 1 + m
        # colours may follow a face's corners on its line; they are skipped with the line's
        # remaining tokens only when the next token cannot start a face: OFF files from
        # trimesh and most tools carry none
    return _arrays(vertices, faces)


def _read_stl(path: Path) -> dict:
    raw = path.read_bytes()
    if len(raw) >= 84:
        (count,) = struct.unpack("<I", raw[80:84])
        if 84 + 50 * count == len(raw):  # binary: 80-byte header, count, 50 bytes a triangle
            records = np.frombuffer(raw, dtype=np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)),
                                                         ("attribute", "<u2")]), count=count, offset=84)
            corners = records["corners"].astype(np.float64).reshape(-1, 3)
            return _welded(corners)
    text = raw.decode("latin-1")
    if not text.lstrip().lower().startswith("solid"):
        raise MeshFileError("it is neither a binary STL (its size disagrees with its triangle count) nor an "
                            "ASCII one (it does not start with 'solid')")
    corners = []
    for n, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if parts and parts[0].lower() == "vertex":
            if len(parts) != 4:
                raise MeshFileError(f"line {n}: a vertex needs 3 coordinates")
            corners.append([_number(t, "coordinate", n) for t in parts[1:]])
    if len(corners) % 3:
        raise MeshFileError(f"it holds {len(corners)} corners, not a whole number of triangles")
    return _welded(np.asarray(corners, np.float64).reshape(-1, 3))


def weld(vertices, faces):
    """(vertices, faces) with the vertices of equal position merged, in order of first use."""
    vertices = np.asarray(vertices)
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return vertices[first[order]], rank[np.asarray(inverse).ravel()][np.asarray(faces)]


def _welded(corners) -> dict:
    """STL's triangles, each with its own three corners, welded by position."""
    if not np.isfinite(corners).all():
        raise MeshFileError("its corners hold NaN or infinite coordinates")
    if len(corners) == 0:
        return {"vertices": corners, "faces": np.zeros((0, 3), np.int64)}
    vertices, faces = weld(corners, np.arange(len(corners)).reshape(-1, 3))
    return {"vertices": vertices, "faces": faces, "welded": True}


def _read_ply(path: Path) -> dict:
    try:
        import trimesh
    except ImportError as err:  # pragma: no cover
        raise ImportError("Mesh.from_file needs trimesh for PLY files: pip install trimesh") from err
    try:
        loaded = trimesh.load(str(path), file_type="ply", force="mesh", process=False)
    except ImportError as err:  # a module trimesh needs for this file is missing
        raise MeshFileError(f"trimesh could not read it: {err}") from None
    except Exception as err:  # trimesh raises what its parsers raise; all of it means a bad file
        raise MeshFileError(f"{type(err).__name__}: {str(err).strip() or 'unreadable'}") from None
    return _arrays(getattr(loaded, "vertices", np.zeros((0, 3))), getattr(loaded, "faces", np.zeros((0, 3))))

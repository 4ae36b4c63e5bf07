"""Animations (dynamic meshes): frames sharing one connectivity.

Stored as ``.npz`` with ``vertices`` (frames, n, 3) and ``faces`` (m, 3), plus
optional per-vertex-per-frame fields (frames, n); or read from a folder of frame
meshes that all have the same faces, in natural order of their names (digit
runs compare as numbers: ``frame2.ply`` before ``frame10.ply``; hidden files,
whose names start with a dot, and subfolders are not frames), whose
per-vertex properties present in every frame become the fields (except
properties named ``vertices`` or ``faces``, the ``.npz`` names of the geometry).
Written as ``.npz`` (:func:`animation_to_bytes`) or as one binary PLY per frame
(:func:`animation_to_frames`, ``frame_0000.ply`` and on), which reads back the same.
"""

from __future__ import annotations

import hashlib
import io
import os
import re
import stat
import zipfile
from dataclasses import dataclass, field

import numpy as np

from geoproc.errors import InputError, first_line
from geoproc.fileio import file_extension, read_input_bytes, sha256_bytes
from geoproc.mesh.read import require_coordinates_in_range
from geoproc.mesh.validate import require_indices_below

GEOMETRY_KEYS = ("vertices", "faces")
"""The ``.npz`` names of the positions and triangles: no field can take them."""


@dataclass
class Animation:
    """Frames of a mesh with fixed connectivity.

    Attributes
    ----------
    V : (T, n, 3) float64 vertex positions per frame.
    F : (m, 3) int64 triangles shared by every frame.
    fields : dict of str to (T, n) float64 per-vertex values per frame.
    path : str, the file or folder read.
    frame_files : list of str, for a folder the frame files in the order read (else empty).
    sha256 : str
        Hex SHA-256 of the bytes parsed: of the ``.npz`` file; for a folder, of
        its frame files sorted by name, each as its name, NUL and its hex
        SHA-256 (empty when not read from disk).
    frame_sha256 : list of str, for a folder the hex SHA-256 of each frame file, as ``frame_files``.
    unread : list of str
        What the input holds and the animation does not carry: arrays of a
        ``.npz`` (not numeric, or not shaped (frames, n)), each as its name and
        shape; for a folder, the frames' face properties, vertex properties
        not in every frame (or named ``vertices`` or ``faces``), and what no
        frame's reader carries (list properties, other elements).
    """

    V: np.ndarray
    F: np.ndarray
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    path: str = ""
    frame_files: list[str] = field(default_factory=list)
    sha256: str = ""
    frame_sha256: list[str] = field(default_factory=list)
    unread: list[str] = field(default_factory=list)

    @property
    def n_frames(self) -> int:
        return int(self.V.shape[0])


def is_animation_path(path: str) -> bool:
    """True for a ``.npz`` file or a folder (of frame meshes)."""
    return str(path).lower().endswith(".npz") or os.path.isdir(str(path))


def load_animation(path: str | os.PathLike) -> Animation:
    """Read an animation from ``.npz`` or a folder of frame meshes.

    Raises
    ------
    InputError
        Missing file, missing or misshapen arrays, non-finite positions, face
        indices out of range, or frames whose connectivity differs.
    """
    name = os.fspath(path)
    if os.path.isdir(name):
        return _load_frame_folder(name)
    raw = read_input_bytes(name, "animation file")
    if not raw:
        raise InputError(name, "file is empty")
    data, skipped = _npz_arrays(raw, name)
    V = data.pop("vertices")
    if V.dtype.kind not in "fiu":
        raise InputError(name, f"'vertices' must hold real numbers, got dtype {V.dtype}")
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(data.pop("faces"))
    if V.ndim != 3 or V.shape[2] != 3 or V.shape[0] < 1 or V.shape[1] < 1:
        raise InputError(name, f"'vertices' has shape {V.shape}; expected (frames, n, 3)")
    if F.ndim == 3 and len(F):  # faces per frame (k, m, 3): one per frame, all the same
        if len(F) != len(V):
            raise InputError(name, f"'faces' has shape {F.shape}: {len(F)} frames of faces for {len(V)} of "
                             "vertices; expected (m, 3), or (frames, m, 3) with every frame's the same")
        if (F != F[:1]).any():
            bad = int(np.flatnonzero((F != F[:1]).reshape(len(F), -1).any(axis=1))[0])
            raise InputError(name, f"frame {bad} has a different connectivity from frame 0")
        F = F[0]
    if F.ndim == 2 and F.shape[1] == 3 and F.size == 0:
        F = F.astype(np.int64)  # no faces (a moving cloud), as np.zeros((0, 3)) stores them: float64
    if F.ndim != 2 or F.shape[1] != 3 or not np.issubdtype(F.dtype, np.integer):
        raise InputError(name, f"'faces' has shape {F.shape} ({F.dtype}); expected (m, 3) integers")
    _validate(V, F, name)
    fields, unread = {}, skipped
    for k, v in data.items():  # per-vertex numeric arrays travel as fields; others are named as unread
        if k == "outlier" and v.shape != V.shape[:2]:  # the flags denoise --outliers scores against
            raise InputError(name, f"'outlier' has shape {v.shape}; expected (frames, n) = {V.shape[:2]}")
        if v.dtype.kind == "c" and k == "outlier":  # left out, the flags to score against would be lost
            raise InputError(name, f"'{k}' must hold real numbers, got dtype {v.dtype}")
        if v.dtype.kind in "fiub" and v.shape == V.shape[:2]:
            fields[k] = np.asarray(v, dtype=np.float64)
        else:  # (a complex field is named as such: it is shaped as one, but no property holds it)
            unread.append(f"{k} {tuple(v.shape)}" + (" complex" if v.dtype.kind == "c" else ""))
    return Animation(V, F.astype(np.int64), fields, name, sha256=sha256_bytes(raw), unread=unread)


def _npz_arrays(raw: bytes, name: str) -> tuple[dict[str, np.ndarray], list[str]]:
    """The arrays of a ``.npz`` file's bytes, by name, and the members left out.

    ``vertices`` and ``faces`` must be numeric ``.npy`` members (InputError
    otherwise); any other member that is not one (a text file, an object array,
    which would need unpickling) is left out, named with the reason. A damaged
    ``.npy`` member (fewer bytes than its header declares) is an InputError
    whatever its name: a truncated ``outlier`` member had been left out as an
    object array, and the outlier scores lost their precision and recall.
    """
    try:
        z = np.load(io.BytesIO(raw), allow_pickle=False)
    except Exception as exc:  # not a zip, a damaged one
        raise InputError(name, f"not a readable .npz animation ({type(exc).__name__})") from None
    if not isinstance(z, np.lib.npyio.NpzFile):  # a lone .npy array
        raise InputError(name, "not a .npz archive (a single array; an animation needs 'vertices' and 'faces')")
    data, skipped = {}, []
    with z:
        for key in GEOMETRY_KEYS:
            if key not in z.files:
                raise InputError(name, f"missing array '{key}' (an animation needs 'vertices' (frames, n, 3) "
                                       "and 'faces')")
        for key in z.files:
            try:
                arr = z[key]
            except ValueError as exc:
                if "pickle" not in str(exc):  # fewer bytes than its header's shape: damaged, not left out
                    raise InputError(name, f"member '{key}' is damaged ({first_line(exc)})") from None
                arr = None  # an object array: numpy would have to unpickle it
                why = "an object array (pickled Python objects)"
            except Exception as exc:  # a damaged member: its data would be lost without a word
                raise InputError(name, f"member '{key}' is damaged ({type(exc).__name__})") from None
            else:
                why = "not a .npy array"
            if isinstance(arr, np.ndarray):
                data[key] = arr
            elif key in GEOMETRY_KEYS:
                raise InputError(name, f"'{key}' is {why}; an animation's '{key}' is a numeric array")
            else:
                skipped.append(f"{key} ({why})")
    return data, skipped


def _validate(V: np.ndarray, F: np.ndarray, name: str) -> None:
    if not np.isfinite(V).all():
        t, i = (int(x) for x in np.argwhere(~np.isfinite(V).all(axis=2))[0])
        raise InputError(name, f"non-finite position (frame {t}, vertex {i})")
    require_coordinates_in_range(V, name)
    require_indices_below(F, V.shape[1], name)


def natural_key(name: str) -> tuple[list, str]:
    """Sort key that compares digit runs as numbers (``f2`` before ``f10``)."""
    parts = re.split(r"(\d+)", name)
    return [int(p) if i % 2 else p for i, p in enumerate(parts)], name


def frame_file_candidates(folder: str) -> list[str]:
    """The names in ``folder`` a frame folder is read from, unsorted: mesh files
    (.obj, .ply, .off, .stl), not hidden (a name starting with a dot), not folders."""
    from geoproc.mesh.read import MESH_FORMATS

    return [f for f in os.listdir(folder) if file_extension(f) in MESH_FORMATS and not f.startswith(".")
            and not os.path.isdir(os.path.join(folder, f))]


def _load_frame_folder(name: str) -> Animation:
    from geoproc.mesh import load_mesh

    files = sorted(frame_file_candidates(name), key=natural_key)
    if not files:
        raise InputError(name, "folder holds no frame meshes (.obj, .ply, .off, .stl)")
    for f in files:  # a pipe named like a frame had blocked the read, a link to /dev/zero filled the memory
        try:
            mode = os.stat(os.path.join(name, f)).st_mode
        except OSError:  # a dangling link: the read below names it
            continue
        if not stat.S_ISREG(mode):
            raise InputError(os.path.join(name, f), "is not a regular file (a pipe or a device): a frame "
                                                    "folder holds mesh files")
    frames, per_frame_fields, digests = [], [], []
    dropped: dict[str, None] = {}  # what a frame holds that the animation does not carry, in order seen
    F0 = None
    for f in files:
        # as stored, but an STL frame holds separate triangles: its coincident corners are merged
        # (in order of first use, the same in every frame whose triangles come in the same order)
        mesh = load_mesh(os.path.join(name, f), clean=file_extension(f) == "stl")
        digests.append(mesh.log.sha256)
        if F0 is None:
            F0 = mesh.F
        elif mesh.F.shape != F0.shape or (mesh.F != F0).any() or len(mesh.V) != len(frames[0]):
            raise InputError(os.path.join(name, f), f"different connectivity from the first frame {files[0]}")
        frames.append(mesh.V)
        per_frame_fields.append({k: np.asarray(v, dtype=np.float64).reshape(len(mesh.V), -1)
                                 for k, v in mesh.vertex_fields.items()})
        dropped.update(dict.fromkeys(f"face {k}" for k in mesh.face_fields))
        dropped.update(dict.fromkeys(mesh.log.unread_properties))
    common = set.intersection(*(set(d) for d in per_frame_fields))
    fields = {k: np.stack([d[k][:, 0] for d in per_frame_fields]) for k in sorted(common - set(GEOMETRY_KEYS))
              if all(d[k].shape[1] == 1 for d in per_frame_fields)}
    seen = dict.fromkeys(k for d in per_frame_fields for k in d)
    unread = [f"vertex {k}" + (" (not in every frame)" if k not in common else "") for k in seen if k not in fields]
    unread += list(dropped)
    folder = hashlib.sha256()
    for f, digest in sorted(zip(files, digests, strict=True)):
        folder.update(os.fsencode(f) + b"\0" + digest.encode())
    return Animation(np.stack(frames), F0, fields, name, [os.path.join(name, f) for f in files],
                     sha256=folder.hexdigest(), frame_sha256=digests, unread=unread)


def animation_to_bytes(anim: Animation) -> bytes:
    """``.npz`` bytes with fixed zip timestamps, so equal data give equal bytes."""
    clash = sorted(set(anim.fields) & set(GEOMETRY_KEYS))
    if clash:
        raise ValueError(f"a field named {clash[0]!r} would replace the geometry in the .npz")
    buf = io.BytesIO()
    arrays = {"vertices": np.ascontiguousarray(anim.V, dtype=np.float64),
              "faces": np.ascontiguousarray(anim.F, dtype=np.int64)}
    arrays.update({k: np.ascontiguousarray(v, dtype=np.float64) for k, v in sorted(anim.fields.items())})
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
        for key, arr in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            body = io.BytesIO()
            np.lib.format.write_array(body, arr, allow_pickle=False)
            zf.writestr(info, body.getvalue())
    return buf.getvalue()


FRAME_FILE = re.compile(r"frame_[0-9]+\.ply\Z")
"""Names of the files a frame-folder output holds (``frame_0000.ply``, ...)."""

PROPERTY_NAME = re.compile(r"[!-~]+\Z")
"""Field names a frame's PLY vertex property can take (other than x, y, z): a
PLY header's word, printable ASCII without spaces (``my-field``, ``1st``; only
identifiers had been taken, where a mesh's PLY keeps any such word)."""


def names_folder(path: str) -> bool:
    """True when an output path names a folder: it ends with ``/`` or is one."""
    return path.endswith(("/", os.sep)) or os.path.isdir(path)


def frame_file_names(n_frames: int) -> list[str]:
    """``frame_0000.ply`` ... for ``n_frames`` frames, zero-padded to at least
    four digits and to the same width, so that names sort in frame order."""
    width = max(4, len(str(max(n_frames - 1, 0))))
    return [f"frame_{t:0{width}d}.ply" for t in range(n_frames)]


def unwritable_frame_fields(anim: Animation) -> list[str]:
    """Names of ``anim``'s fields that no PLY vertex property can take (a
    ``.npz`` member may be named anything): not a word of printable ASCII,
    or x, y, z, or end_header (which trimesh's reader takes for the header's
    end)."""
    return [k for k in anim.fields if not PROPERTY_NAME.match(k) or k in ("x", "y", "z", "end_header")]


def animation_to_frames(anim: Animation) -> list[tuple[str, bytes]]:
    """One binary PLY per frame, as (file name, bytes): positions as doubles,
    each field as a double vertex property, the faces (none for a moving point
    cloud) in every frame. Read back as a frame folder, it gives the same
    positions, faces and fields.

    Raises
    ------
    ValueError
        A field whose name no PLY property can take (see
        :func:`unwritable_frame_fields`).
    """
    from geoproc.mesh import Mesh, mesh_to_bytes

    bad = unwritable_frame_fields(anim)
    if bad:
        raise ValueError(f"field {bad[0]!r} cannot be a PLY vertex property")
    F = np.ascontiguousarray(anim.F, dtype=np.int64)
    out = []
    for t, name in enumerate(frame_file_names(anim.n_frames)):
        fields = {k: np.asarray(v[t], dtype=np.float64) for k, v in sorted(anim.fields.items())}
        out.append((name, mesh_to_bytes(Mesh(np.asarray(anim.V[t], dtype=np.float64), F, fields), "ply")))
    return out


def foreign_frame_files(folder: str) -> list[str]:
    """The files in ``folder`` that reading it as an animation would take as
    frames but that a frame-folder output does not write (mesh files not named
    ``frame_N.ply``), sorted; [] for a folder that is not there."""
    if not os.path.isdir(folder):
        return []
    return sorted(f for f in frame_file_candidates(folder) if not FRAME_FILE.match(f))


def frame_folder_problem(folder: str) -> str | None:
    """Why an existing ``folder`` cannot take a frame-folder output, or None:
    it holds mesh files other than ``frame_N.ply`` (read back, they would be
    taken for frames), or a ``frame_N.ply`` that is not a plain file (a
    symbolic link, a pipe, a device or a folder: a frame written there would
    go elsewhere, or block)."""
    foreign = foreign_frame_files(folder)
    if foreign:
        more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
        return (f"holds mesh files other than frame_N.ply ({foreign[0]}{more}), which would be read back as "
                "frames; name a new folder or one without other mesh files")
    if not os.path.isdir(folder):
        return None
    for name in sorted(os.listdir(folder)):
        full = os.path.join(folder, name)
        if FRAME_FILE.match(name) and (os.path.islink(full) or not os.path.isfile(full)):
            what = "a symbolic link" if os.path.islink(full) else "not a plain file"
            return f"{name} is {what}; the frames are written as plain files (remove it, or name another folder)"
    return None


def stale_frame_files(folder: str, written: list[str]) -> list[str]:
    """The ``frame_N.ply`` files in ``folder`` other than those ``written``
    (left by an earlier run with more frames, or another name width)."""
    keep = set(written)
    return sorted(f for f in os.listdir(folder) if FRAME_FILE.match(f) and f not in keep
                  and not os.path.isdir(os.path.join(folder, f)))

"""The checkpoint file: data only, never code.

A checkpoint is a NumPy ``.npz`` archive (a zip of ``.npy`` arrays) that `np.load(path, allow_pickle=False)`
opens. Its member ``manifest`` holds UTF-8 JSON::

    {"format": 2, "state": {...}, "sha256": {"agent/online": "<hex>", ...}}

``state`` is the saved tree (configuration, counters, metric rows, RNG states as JSON); each array in it
is replaced by ``{"__array__": KEY}`` (or ``{"__tensor__": KEY}`` for a torch tensor) and stored as the member
``KEY.npy``. ``sha256`` is the SHA-256 of each member's bytes, checked on reading. Arrays are read with
``allow_pickle=False``, so no object arrays, and nothing in the file is ever executed.

Format 1 was a pickle (``checkpoint.pkl``); it is refused by name (`legacy_message`), never opened.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import zipfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from train.storage.fileio import atomic_file
from train.storage.safeio import UnsafeFileError, loads_json, open_regular, read_npy

FORMAT = 2
"""Version of the checkpoint layout written and read here."""
CHECKPOINT_NAME = "checkpoint.npz"
"""File name of a run's checkpoint."""
LEGACY_NAME = "checkpoint.pkl"
"""File name of format-1 (pickled) checkpoints, which are refused."""
MANIFEST = "manifest"
"""Archive member holding the JSON manifest."""
MAX_MANIFEST_BYTES = 256 << 20
"""A larger manifest is refused as not made by ecorl."""


class CheckpointError(ValueError):
    """A checkpoint that cannot be read (the message says why and what to do)."""


def legacy_message(path: Path) -> str:
    """The refusal of a pickled (format 1) checkpoint."""
    return (f"{path} is a pickled checkpoint (ecorl checkpoint format 1), which this ecorl (format {FORMAT}, "
            f"{CHECKPOINT_NAME}) never opens because loading a pickle can run code; re-run the training in a new "
            f"--out directory (its config.json and metrics.csv stay readable)")


# ---- flattening a state tree ---------------------------------------------------------------------------


def flatten(tree: Any, prefix: str = "") -> tuple[Any, dict[str, np.ndarray]]:
    """Split ``tree`` into a JSON-friendly tree and its arrays (keyed by their path, e.g. ``agent/online``)."""
    arrays: dict[str, np.ndarray] = {}
    torch = sys.modules.get("torch")  # not imported: no tensor can be in the tree (commands that need no torch)

    def walk(node: Any, path: str) -> Any:
        if torch is not None and isinstance(node, torch.Tensor):
            arrays[path] = node.detach().cpu().numpy()
            return {"__tensor__": path}
        if isinstance(node, np.ndarray):
            arrays[path] = node
            return {"__array__": path}
        if isinstance(node, dict):
            return {str(k): walk(v, f"{path}/{k}" if path else str(k)) for k, v in node.items()}
        if isinstance(node, (list, tuple)):
            return [walk(v, f"{path}/{i}") for i, v in enumerate(node)]
        if isinstance(node, np.generic):
            return node.item()
        if node is None or isinstance(node, (bool, int, float, str)):
            return node
        raise TypeError(f"cannot store {type(node).__name__} at {path!r} in a checkpoint (data only)")

    return walk(tree, prefix), arrays


def unflatten(tree: Any, arrays: dict[str, np.ndarray | None]) -> Any:
    """Put arrays back into a tree made by `flatten` (missing ones become None)."""
    if isinstance(tree, dict):
        if set(tree) == {"__array__"}:
            return arrays.get(tree["__array__"])
        if set(tree) == {"__tensor__"}:
            value = arrays.get(tree["__tensor__"])
            if value is None:
                return None
            import torch

            return torch.from_numpy(value)
        return {k: unflatten(v, arrays) for k, v in tree.items()}
    if isinstance(tree, list):
        return [unflatten(v, arrays) for v in tree]
    return tree


def array_keys(tree: Any) -> list[str]:
    """The array keys referenced by a flattened tree."""
    if isinstance(tree, dict):
        if set(tree) in ({"__array__"}, {"__tensor__"}):
            return [next(iter(tree.values()))]
        return [k for v in tree.values() for k in array_keys(v)]
    if isinstance(tree, list):
        return [k for v in tree for k in array_keys(v)]
    return []


# ---- writing -------------------------------------------------------------------------------------------


class _Hashing:
    """A file wrapper that hashes every byte written through or read from it."""

    def __init__(self, file: BinaryIO) -> None:
        self.file, self.hash = file, hashlib.sha256()

    def write(self, data) -> int:
        self.hash.update(data)
        return self.file.write(data)

    def read(self, size: int = -1) -> bytes:
        data = self.file.read(size)
        self.hash.update(data)
        return data


def _write_member(zf: zipfile.ZipFile, key: str, array: np.ndarray) -> str:
    """Store one array as ``KEY.npy`` (streamed, uncompressed); return the SHA-256 of its bytes."""
    if array.dtype.hasobject:
        raise TypeError(f"checkpoint array {key!r} holds Python objects (dtype {array.dtype}); data only")
    with zf.open(f"{key}.npy", "w", force_zip64=True) as member:
        hashing = _Hashing(member)
        np.lib.format.write_array(hashing, np.asanyarray(array), allow_pickle=False)
    return hashing.hash.hexdigest()


def write_checkpoint(path: str | Path, state: dict[str, Any]) -> Path:
    """Write ``state`` (nested dicts/lists of JSON values, arrays and tensors) atomically to ``path``."""
    tree, arrays = flatten(state)
    with atomic_file(path) as f, zipfile.ZipFile(f, "w", zipfile.ZIP_STORED, allowZip64=True) as zf:
        digests = {key: _write_member(zf, key, array) for key, array in arrays.items()}
        manifest = json.dumps({"format": FORMAT, "state": tree, "sha256": digests}).encode()
        _write_member(zf, MANIFEST, np.frombuffer(manifest, dtype=np.uint8))
    return Path(path)


# ---- reading -------------------------------------------------------------------------------------------


def _corrupt(path: Path, why: str) -> CheckpointError:
    return CheckpointError(f"{path} is corrupt or not an ecorl checkpoint ({why}); restore it from a backup or "
                           f"start a fresh run in another --out directory")


def _member_info(zf: zipfile.ZipFile, path: Path, key: str) -> zipfile.ZipInfo:
    """The zip directory's entry of ``KEY.npy``: stored as ecorl stores it (never compressed)."""
    try:
        info = zf.getinfo(f"{key}.npy")
    except KeyError:
        raise _corrupt(path, f"no array {key!r}") from None
    if info.compress_type != zipfile.ZIP_STORED:
        raise _corrupt(path, f"member {key!r} is compressed; ecorl stores checkpoint arrays uncompressed")
    return info


def _read_member(zf: zipfile.ZipFile, path: Path, key: str) -> tuple[np.ndarray, str]:
    """One array (never unpickled) and the SHA-256 of its member's bytes; sizes checked before reading."""
    info = _member_info(zf, path, key)
    with zf.open(info) as member:
        hashing = _Hashing(member)
        try:
            array = read_npy(hashing, info.file_size, f"member {key!r}")
        except ValueError as err:
            raise _corrupt(path, str(err)) from None
        if hashing.read(1):
            raise _corrupt(path, f"member {key!r} has trailing bytes")
    return array, hashing.hash.hexdigest()


def _read_manifest(zf: zipfile.ZipFile, path: Path) -> dict[str, Any]:
    """The manifest, its format checked."""
    if f"{MANIFEST}.npy" not in zf.namelist():
        raise _corrupt(path, "no manifest")
    info = _member_info(zf, path, MANIFEST)
    if info.file_size > MAX_MANIFEST_BYTES:
        raise _corrupt(path, f"manifest of {info.file_size} bytes")
    raw, _ = _read_member(zf, path, MANIFEST)
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise _corrupt(path, "manifest is not UTF-8 bytes")
    manifest = loads_json(raw.tobytes().decode(), f"the manifest of {path}")
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        found = manifest.get("format") if isinstance(manifest, dict) else None
        raise CheckpointError(f"{path} has checkpoint format {found!r}; this ecorl reads format {FORMAT}: re-run "
                              f"the training with this version in a new --out directory")
    if not isinstance(manifest.get("state"), dict) or not isinstance(manifest.get("sha256"), dict):
        raise _corrupt(path, "manifest lacks its state or digests")
    return manifest


def default_limit() -> int:
    """The most bytes of arrays a checkpoint may make ecorl allocate when no configuration bounds it: half
    of this machine's memory.
    """
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2
    except (ValueError, OSError, AttributeError):
        return 64 << 30


def read_checkpoint(path: str | Path, keys: Iterable[str] | None = None, limit: int | None = None) -> dict[str, Any]:
    """Read and verify a checkpoint; ``keys`` limits the arrays loaded (the others come back as None).

    ``limit`` bounds the bytes of the arrays read (default `default_limit`): the sizes the zip directory and
    each array header declare are checked against it before anything is decompressed or allocated.
    Raises `CheckpointError` (one line: why, and what to do) for anything that is not an intact format-2
    checkpoint, including a pickled format-1 file, which is never opened.
    """
    path = Path(path)
    if path.name == LEGACY_NAME or (not path.exists() and (path.parent / LEGACY_NAME).exists()):
        raise CheckpointError(legacy_message(path.parent / LEGACY_NAME))
    limit = default_limit() if limit is None else limit
    try:
        with open_regular(path) as file, zipfile.ZipFile(file) as zf:
            manifest = _read_manifest(zf, path)
            wanted = array_keys(manifest["state"]) if keys is None else list(keys)
            declared = sum(_member_info(zf, path, key).file_size for key in wanted)
            if declared > limit:
                raise CheckpointError(f"{path} declares {declared} bytes of arrays, more than the {limit} a run "
                                      f"of its settings can hold; it is not a checkpoint ecorl wrote for this run: "
                                      f"start a fresh run in another --out directory")
            arrays: dict[str, np.ndarray | None] = {}
            for key in wanted:
                if key not in manifest["sha256"]:
                    raise _corrupt(path, f"no array {key!r}")
                array, digest = _read_member(zf, path, key)
                if digest != manifest["sha256"][key]:
                    raise _corrupt(path, f"checksum mismatch in {key!r}: truncated or altered")
                arrays[key] = array
            return unflatten(manifest["state"], arrays)
    except CheckpointError:
        raise
    except UnsafeFileError as err:
        raise CheckpointError(str(err)) from None
    except FileNotFoundError:
        raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError, KeyError, ValueError, UnicodeError,
            TypeError, json.JSONDecodeError) as err:
        raise _corrupt(path, f"{type(err).__name__}: {err}".replace("\n", " ")) from None

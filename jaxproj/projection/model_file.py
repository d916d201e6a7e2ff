"""The model file: ``save`` / ``load`` a ``Model`` through one ``.npz``, and every check on read.

A file holds every chain's arrays unpadded (``chain<c>.human``, ``chain<c>.forward.out``, ...),
the ``BuildConfig`` (with the robot's name: a file without one is the default robot's; with the
UTKinect-Action3D people it trained on: a file without them trained on none), the chain
layout, the robot's driven joints and IK constants and a format version in a JSON ``meta``
entry; for a robot read from a robot file, the file and its MJCF too (``meta["robot_file"]``,
``robot_file.embed``), so that ``load`` registers that robot where it is not registered (another
machine, a fresh process without the robot's folder). ``load`` refuses (``InputError`` naming
the file) anything that is not such a file of this jaxproj's format version and chain layout,
before an array reaches JAX.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from jaxproj import robots
from jaxproj._internal.atomic import check_output, write_npz
from jaxproj.errors import ConfigError, InputError
from jaxproj.projection.build import Model
from jaxproj.projection.config import BuildConfig
from jaxproj.projection.elm import ELMBank
from jaxproj.projection.projector import make_projector
from jaxproj.projection.stacked import chain_inputs, layout_of, stack_projectors
from jaxproj.robots import robot_file

FORMAT = "jaxproj-projector"
FORMAT_VERSION = 3
"""3: one projector per kinematic chain (``chain<c>.*`` arrays, the layout in the metadata);
2: kernel output weights stored ``(n_kernels, d_out, hidden)``; 1: ``(hidden, d_out)``."""


_BANK_FIELDS = ("w", "inv_scale", "bias", "out", "offset", "neighbours")


# Array shapes of one chain in a model file: K landmarks, m descriptor columns and n joints of
# the chain (known from the layout), Hf / Hb hidden units and kf / kb neighbours (read).
def _bank_shapes(bank: str, d_in: str, d_out: str, hidden: str, k: str) -> dict:
    """The ``_ARRAY_SHAPES`` entries of one kernel bank, in ``_BANK_FIELDS`` order."""
    shapes = ((hidden, d_in), ("K",), ("K", hidden), ("K", d_out, hidden), ("K", d_out), ("K", k))
    return {f"{bank}.{f}": shape for f, shape in zip(_BANK_FIELDS, shapes, strict=True)}


_ARRAY_SHAPES: dict[str, tuple[str, ...]] = {
    "human": ("K", "m"),
    "robot": ("K", "n"),
    "counts": ("K",),
    **_bank_shapes("forward", "m", "n", "Hf", "kf"),
    **_bank_shapes("backward", "n", "m", "Hb", "kb"),
}


def save(model: Model, path: str | Path, *, overwrite: bool = True) -> None:
    """Write a model to one ``.npz``: every chain's arrays (unpadded), the config, the chain
    layout and a format version.

    The file is written under a temporary name beside ``path`` and then renamed
    (``jaxproj._internal.atomic``), so an interrupted or failed save never leaves a half-written
    model; the zip members carry fixed timestamps, so the same model gives a byte-identical file.
    No folder is created: the folder of ``path`` must exist (as for ``jaxproj build --out``).
    ``overwrite`` (default ``True``, as numpy's savers) replaces an existing file; ``False``
    refuses it (``jaxproj build`` passes ``--force``, off by default).

    Raises:
      ConfigError: the folder of ``path`` does not exist or is not a folder, or ``path``
        exists and ``overwrite`` is false (nothing written).
      InputError: the file cannot be written.
    """
    check_output(path, overwrite=overwrite)  # before any array is copied off the device
    sp = model.projector
    lay = sp.layout
    spec = model.robot
    arrays: dict[str, np.ndarray] = {}
    for c in range(lay.n_chains):
        p = sp.chain(c)
        arrays[f"chain{c}.human"] = np.asarray(p.human)
        arrays[f"chain{c}.robot"] = np.asarray(p.robot)
        arrays[f"chain{c}.counts"] = np.asarray(model.counts[c])
        for name, bank in (("forward", p.forward), ("backward", p.backward)):
            for f in _BANK_FIELDS:
                arrays[f"chain{c}.{name}.{f}"] = np.asarray(getattr(bank, f))
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "config": asdict(model.config),
        "chains": {"names": list(lay.names), "inputs": lay.inputs, "outputs": lay.outputs},
        "bandwidth": list(model.bandwidth),
        "n_train": model.n_train,
        "deviation_scale": model.deviation_scale,
        "driven_joints": list(spec.driven_joints),
        "ik": dict(spec.ik_constants),
    }
    robot_doc = robot_file.embed(spec)
    if robot_doc is not None:  # a robot from a file travels with the model
        meta["robot_file"] = robot_doc
    arrays = {"meta": np.array(json.dumps(meta)), **arrays}
    write_npz(path, arrays, overwrite=overwrite)


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def load(path: str | Path) -> Model:
    """Read a model written by ``save``.

    Raises:
      InputError: naming the file: missing, a directory, not an npz archive, truncated or
        corrupt, not a jaxproj model, another format version (a newer one: upgrade jaxproj), a
        robot that is not registered, a chain layout other than this jaxproj's for the model's
        configuration, a missing, mis-shaped or non-finite array.
    """
    path = Path(path)
    data = _read_arrays(path)
    meta = _read_meta(path, data)
    config = _config(path, meta)
    spec = config.robot_spec
    chains = spec.chain_set(config.chains)
    _check_layout(path, meta, config, data)
    try:
        bandwidth = tuple(float(b) for b in meta["bandwidth"])
        n_train = int(meta["n_train"])
        # a file written before models were calibrated has none: its robot's scale is used
        scale = meta.get("deviation_scale")
        scale = None if scale is None else float(scale)
        if scale is not None and not (np.isfinite(scale) and scale > 0):
            raise ValueError(f"deviation_scale {scale} is not finite and > 0")
        if len(bandwidth) != len(chains):
            raise ValueError(f"{len(bandwidth)} bandwidths for {len(chains)} chains")
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(path, f"corrupt model metadata ({_one_line(e)})") from None
    projectors, counts = [], []
    for c, ch in enumerate(chains):
        a = _chain_arrays(path, data, c, len(chain_inputs(config, ch)), len(spec.chain_joints(ch)))
        banks = {}
        for name in ("forward", "backward"):
            f = {f: a[f"{name}.{f}"] for f in _BANK_FIELDS}
            banks[name] = ELMBank(
                **{k: jnp.asarray(v) for k, v in f.items()},
                n_kernels=int(f["out"].shape[0]),
                hidden=int(f["out"].shape[2]),
                d_in=int(f["w"].shape[1]),
                d_out=int(f["out"].shape[1]),
                k=int(f["neighbours"].shape[1]),
            )
        joints = list(spec.chain_joints(ch))
        projectors.append(
            make_projector(
                a["human"],
                a["robot"],
                banks["forward"],
                banks["backward"],
                spec.lower_driven[joints],
                spec.upper_driven[joints],
            )
        )
        counts.append(a["counts"])
    try:
        stacked = stack_projectors(projectors, layout_of(config, projectors))
    except (TypeError, ValueError) as e:
        raise InputError(path, f"inconsistent model file ({_one_line(e)})") from None
    return Model(stacked, config, bandwidth, tuple(counts), n_train, scale)


def read_config(path: str | Path) -> BuildConfig:
    """The ``BuildConfig`` a model file records (its robot, chains, bones, mirror, ...), read
    from its metadata alone, without its arrays: what a caller checks its other settings against
    before ``load`` (``jaxproj retarget`` refuses a conflicting option before any work).

    Raises:
      InputError: as ``load`` for the file and its metadata (the arrays are checked by
        ``load``).
    """
    path = Path(path)
    data = _read_arrays(path, ("meta",))
    if "meta" not in data:  # not a model: name the arrays it holds, as load does
        data = _read_arrays(path)
    return _config(path, _read_meta(path, data))


def _read_arrays(path: Path, keys: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
    """The arrays of the model file ``path`` (only ``keys`` of them, where given and present),
    or InputError naming it: missing, a folder, not an npz archive, truncated or corrupt."""
    if path.is_dir():
        raise InputError(path, "is a directory, not a model file")
    if not path.is_file():
        raise InputError(path, "model file not found")
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
            if head != b"PK\x03\x04":
                what = "an empty file" if not head else "not an npz archive"
                raise InputError(path, f"not a jaxproj model ({what}; see `jaxproj build`)")
            fh.seek(0)
            with np.load(fh, allow_pickle=False) as z:
                names = z.files if keys is None else [k for k in keys if k in z.files]
                return {k: z[k] for k in names}
    except InputError:
        raise
    except Exception as e:  # zipfile / zlib / numpy errors of a truncated or corrupt archive
        raise InputError(path, f"not a readable model file ({_one_line(e)})") from None


def _config(path: Path, meta: dict) -> BuildConfig:
    """The checked ``BuildConfig`` of a model file's ``meta``."""
    doc = meta.get("robot_file")
    name = meta.get("config", {}).get("robot") if isinstance(meta.get("config"), dict) else None
    if (
        isinstance(doc, dict)
        and name is not None
        and doc.get("name") == name  # the copy of the robot the configuration names, no other
        and name not in robots.names()
    ):
        try:  # a robot from a file, not registered here: the model's own copy
            robots.register(robot_file.from_embedded(doc))
        except ConfigError as e:
            raise InputError(path, f"its embedded robot does not load ({_one_line(e)})") from None
    try:
        # a file written before BuildConfig.utkinect_people existed trained on MSR Action3D
        # (or the user's data) alone: it must not read as trained on the default UTKinect people
        return BuildConfig(**{"utkinect_people": (), **meta["config"]})
    except (KeyError, TypeError, ValueError, ConfigError) as e:
        raise InputError(path, f"invalid model configuration ({_one_line(e)})") from None


def _read_meta(path: Path, data: dict[str, np.ndarray]) -> dict:
    """The checked ``meta`` entry: a jaxproj model of this format version."""
    if "meta" not in data:
        found = ", ".join(sorted(data)[:5]) or "none"
        raise InputError(path, f"not a jaxproj model (no 'meta' entry; arrays found: {found})")
    try:
        meta = json.loads(str(data["meta"]))
    except (json.JSONDecodeError, TypeError, ValueError):
        raise InputError(path, "corrupt model metadata (not JSON)") from None
    if not isinstance(meta, dict):
        raise InputError(path, "corrupt model metadata (not a JSON object)")
    if meta.get("format") != FORMAT:
        raise InputError(path, f"not a jaxproj model (format {meta.get('format')!r})")
    version = meta.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise InputError(path, f"corrupt model metadata (format_version {version!r})")
    if version > FORMAT_VERSION:
        raise InputError(
            path,
            f"model format version {version} was written by a newer jaxproj (this one reads "
            f"version {FORMAT_VERSION}): upgrade jaxproj, or rebuild the model with "
            "`jaxproj build`",
        )
    if version != FORMAT_VERSION:
        raise InputError(
            path,
            f"model format version {version} is not supported (this jaxproj reads version "
            f"{FORMAT_VERSION}); rebuild it with `jaxproj build`",
        )
    return meta


def _check_layout(path: Path, meta: dict, config: BuildConfig, data: dict) -> None:
    """``InputError`` unless the file's chains are this jaxproj's chains for its config."""
    spec = config.robot_spec
    chains = spec.chain_set(config.chains)
    want = {
        "names": [ch.name for ch in chains],
        "inputs": [list(chain_inputs(config, ch)) for ch in chains],
        "outputs": [list(spec.chain_joints(ch)) for ch in chains],
    }
    got = meta.get("chains")
    got = {k: got.get(k) for k in want} if isinstance(got, dict) else {}
    rebuild = "written by another chain layout; rebuild it with `jaxproj build`"
    for key, value in want.items():
        if got.get(key) != value:
            raise InputError(
                path,
                f"chain {key} {got.get(key)} differ from this jaxproj's {value} for "
                f"chains={config.chains!r}: {rebuild}",
            )
    if meta.get("driven_joints") != list(spec.driven_joints):
        raise InputError(path, f"driven joints {meta.get('driven_joints')} differ from "
                               f"{spec.name}'s {list(spec.driven_joints)}: {rebuild}")  # fmt: skip
    held = {k.split(".", 1)[0] for k in data if k != "meta"}
    extra = sorted(held - {f"chain{c}" for c in range(len(chains))})
    if extra:
        raise InputError(
            path, f"arrays {', '.join(extra)} beyond its {len(chains)} chain(s): {rebuild}"
        )


def _chain_arrays(
    path: Path, data: dict[str, np.ndarray], c: int, m: int, n: int
) -> dict[str, np.ndarray]:
    """Chain ``c``'s arrays, checked against ``_ARRAY_SHAPES`` (``InputError`` naming the array:
    missing, mis-shaped, wrong kind, non-finite, neighbour index out of range)."""
    dims: dict[str, int] = {"m": m, "n": n}
    out = {}
    for key, spec in _ARRAY_SHAPES.items():
        name = f"chain{c}.{key}"
        if name not in data:
            raise InputError(path, f"missing array {name!r} (an incomplete or foreign model file)")
        a = data[name]
        integer = key == "counts" or key.endswith("neighbours")
        ok = a.ndim == len(spec) and a.dtype.kind in ("iu" if integer else "f")
        for sym, size in zip(spec, a.shape if ok else (), strict=False):
            ok = ok and dims.setdefault(sym, size) == size and size >= 1
        if not ok:
            want = ", ".join(f"{s}={dims[s]}" if s in dims else s for s in spec)
            kind = "integers" if integer else "floats"
            raise InputError(
                path, f"array {name!r} has shape {a.shape} ({a.dtype}), expected ({want}) {kind}"
            )
        if not integer and not np.isfinite(a).all():
            raise InputError(path, f"array {name!r} has non-finite values")
        out[key] = a
    for bank in ("forward", "backward"):
        nb = out[f"{bank}.neighbours"]
        if nb.min() < 0 or nb.max() >= dims["K"] or nb.shape[1] > dims["K"]:
            raise InputError(path, f"array 'chain{c}.{bank}.neighbours' indexes beyond the "
                                   f"{dims['K']} landmarks")  # fmt: skip
    return out

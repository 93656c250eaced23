"""Running state as plain data: tensors, numbers, strings, None and dicts/lists/tuples of them.

A checkpoint must load with `torch.load(weights_only=True)`, which refuses any pickled class, so
a checkpoint from elsewhere can never run code. The env's running state holds a few small objects
(numpy arrays, TensorDicts, dataclasses of tensors, the device trajectories, the reward sums);
`pack` turns them into plain data with a tag, and `unpack` rebuilds them **on the live objects'
types**: a dataclass is restored into a copy of the env's own instance, an object with
`state_dict`/`load_state_dict` loads into the env's own one. A file therefore never names a class
to build; a tag that does not match the live value is refused.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import torch
from tensordict import TensorDict

TAG = "__plain__"  # the key that marks an encoded value (a dict with it is never user data)
_SCALARS = (bool, int, float, str, type(None))


class PlainStateError(ValueError):
    """A value cannot be stored as plain data, or a stored value does not fit the live one."""


def pack(value):
    """`value` as plain data (tensors are detached copies, so the result never aliases live buffers)."""
    if isinstance(value, _SCALARS):
        return value
    if isinstance(value, torch.Tensor):
        return value.detach().clone()
    if isinstance(value, np.ndarray):
        if value.dtype == object:
            raise PlainStateError("an object array cannot be stored as plain data")
        return {TAG: "ndarray", "data": torch.from_numpy(np.array(value, copy=True))}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, TensorDict):
        return {TAG: "tensordict", "batch_size": list(value.batch_size), "data": pack(value.to_dict())}
    if isinstance(value, torch.device):
        return {TAG: "device", "name": str(value)}
    if isinstance(value, torch.dtype):
        return {TAG: "dtype", "name": str(value).removeprefix("torch.")}
    if isinstance(value, dict):
        if TAG in value:
            raise PlainStateError(f"a dict with the reserved key {TAG!r} cannot be stored")
        return {k: pack(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        items = [pack(v) for v in value]
        return items if isinstance(value, list) else tuple(items)
    if hasattr(value, "state_dict") and hasattr(value, "load_state_dict"):
        return {TAG: "state", "class": type(value).__qualname__, "data": pack(value.state_dict())}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: pack(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return {TAG: "dataclass", "class": type(value).__qualname__, "fields": fields}
    raise PlainStateError(f"a {type(value).__qualname__} cannot be stored as plain data")


def unpack(saved, like=None, device: torch.device | str | None = None, name: str = "state", classes=()):
    """Rebuild `pack` output. `like` is the live value it replaces (the template for dataclasses and
    stateful objects); where it is None, a dataclass is built only if its class is one of `classes`
    (the caller's allowlist). Tensors go to `device` when given. `name` is used in error messages."""
    if isinstance(saved, torch.Tensor):
        return saved.to(device) if device is not None else saved
    if isinstance(saved, dict) and TAG in saved:
        return _unpack_tagged(saved, like, device, name, classes)
    if isinstance(saved, dict):
        like = like if isinstance(like, dict) else {}
        return {k: unpack(v, like.get(k), device, f"{name}.{k}", classes) for k, v in saved.items()}
    if isinstance(saved, (list, tuple)):
        likes = (
            list(like) if isinstance(like, (list, tuple)) and len(like) == len(saved) else [None] * len(saved)
        )
        items = [
            unpack(v, w, device, f"{name}[{i}]", classes)
            for i, (v, w) in enumerate(zip(saved, likes, strict=True))
        ]
        return type(saved)(items)
    if isinstance(saved, _SCALARS):
        return saved
    raise PlainStateError(f"{name}: unexpected stored type {type(saved).__qualname__}")


def _unpack_tagged(saved: dict, like, device, name: str, classes):
    kind = saved[TAG]
    # a file from elsewhere may hold anything under a tag: a wrong type is refused here, as a
    # PlainStateError naming it, never an AttributeError traceback deep in the restore
    want = {"ndarray": ("data", torch.Tensor), "tensordict": ("data", dict), "dataclass": ("fields", dict)}
    if kind in want and not isinstance(saved.get(want[kind][0]), want[kind][1]):
        raise PlainStateError(f"{name}: a stored {kind} without its {want[kind][0]}")
    if kind == "ndarray":
        return saved["data"].cpu().numpy()
    if kind == "tensordict":
        data = unpack(saved["data"], None, device, name)
        return TensorDict(data, batch_size=saved["batch_size"], device=device)
    if kind == "device":
        return torch.device(saved["name"])
    if kind == "dtype":
        dtype = getattr(torch, str(saved["name"]), None)
        if not isinstance(dtype, torch.dtype):
            raise PlainStateError(f"{name}: unknown dtype {saved['name']!r}")
        return dtype
    if kind == "dataclass" and like is None:  # e.g. a step state not computed yet in a fresh env
        allowed = {c.__qualname__: c for c in classes if dataclasses.is_dataclass(c)}
        if saved.get("class") in allowed:
            like = object.__new__(allowed[saved["class"]])
            for f in dataclasses.fields(like):
                object.__setattr__(like, f.name, None)
    if kind in ("state", "dataclass"):
        if like is None or type(like).__qualname__ != saved.get("class"):
            have = "nothing" if like is None else f"a {type(like).__qualname__}"
            raise PlainStateError(f"{name}: the checkpoint holds a {saved.get('class')}, this env {have}")
        if kind == "state":
            like.load_state_dict(unpack(saved["data"], like.state_dict(), device, name))
            return like
        out = copy.copy(like)
        known = {f.name for f in dataclasses.fields(like)}
        if set(saved["fields"]) != known:
            raise PlainStateError(
                f"{name}: saved fields {sorted(saved['fields'])} differ from {sorted(known)}"
            )
        for field, value in saved["fields"].items():
            object.__setattr__(
                out, field, unpack(value, getattr(like, field), device, f"{name}.{field}", classes)
            )
        return out
    raise PlainStateError(f"{name}: unknown stored kind {kind!r}")

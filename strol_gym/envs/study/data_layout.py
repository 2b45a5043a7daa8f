"""Where ``mjData`` keeps its contacts, in bytes, for compiled code that reads them by address.

The offsets come from MuJoCo's own description of its structs (``mujoco.introspect``) laid out
as C lays them out (``ctypes``), then checked against the binding's view of a live ``MjData``:
pointers to known arrays, the time, and the contacts of a sphere resting in a plane. Where any
of it differs (another MuJoCo, a type this does not know), ``contact_layout()`` is None and the
caller keeps reading ``MjData.contact`` in Python.
"""

from __future__ import annotations

import ctypes
import functools
import math
from typing import Any

import mujoco

_SCALARS: dict[str, Any] = {
    "int": ctypes.c_int,
    "unsigned int": ctypes.c_uint,
    "mjtSize": ctypes.c_uint64,
    "size_t": ctypes.c_size_t,
    "uintptr_t": ctypes.c_size_t,
    "mjtBool": ctypes.c_ubyte,
    "mjtByte": ctypes.c_ubyte,
    "char": ctypes.c_char,
    "mjtNum": ctypes.c_double,
    "float": ctypes.c_float,
}
_CHECKED = ("qpos", "qvel", "qacc", "xfrc_applied")
"""Pointer fields of ``mjData`` whose values the binding's arrays show."""
_PROBE = """<mujoco><worldbody><geom name="floor" type="plane" size="1 1 0.1"/>
<body pos="0 0 0.05"><freejoint/><geom name="ball" size="0.1"/></body></worldbody></mujoco>"""
"""A sphere sunk halfway into a plane: one contact, geoms 0 and 1."""


def _ctype(t: Any) -> Any:
    """The ctypes type of an introspected field type (KeyError for one this does not know)."""
    from mujoco.introspect import ast_nodes

    if isinstance(t, ast_nodes.PointerType):
        return ctypes.c_void_p
    if isinstance(t, ast_nodes.ArrayType):
        return _ctype(t.inner_type) * math.prod(t.extents)
    if isinstance(t, ast_nodes.ValueType):
        if t.name in _SCALARS:
            return _SCALARS[t.name]
        return _struct(t.name, None)
    raise KeyError(repr(t))


@functools.cache
def _struct(name: str, last: str | None) -> Any:
    """``name``'s C layout as a ctypes Structure, its fields up to ``last`` (None: all)."""
    from mujoco.introspect import structs

    fields = []
    for f in structs.STRUCTS[name].fields:
        fields.append((f.name, _ctype(f.type)))
        if f.name == last:
            break
    return type(name, (ctypes.Structure,), {"_fields_": fields})


def _value(address: int, at: int, ctype: Any) -> Any:
    return ctype.from_address(address + at).value


@functools.cache
def contact_layout() -> tuple[int, int, int, int, int] | None:
    """(offset of ``ncon`` in ``mjData``, of its ``contact`` pointer, ``sizeof(mjContact)``,
    offsets of ``geom1`` and ``geom2`` in ``mjContact``), checked against the binding; None
    where they cannot be known or do not check."""
    try:
        data_t = _struct("mjData", "contact")
        contact_t = _struct("mjContact", None)
    except (KeyError, ImportError, AttributeError, TypeError):
        return None
    layout = (
        data_t.ncon.offset,
        data_t.contact.offset,
        ctypes.sizeof(contact_t),
        contact_t.geom1.offset,
        contact_t.geom2.offset,
    )
    return layout if _checks(layout, data_t) else None


def _checks(layout: tuple[int, int, int, int, int], data_t: Any) -> bool:
    """Whether the layout reads what the binding shows, on a live ``MjData`` of ``_PROBE``."""
    ncon_at, contact_at, size, geom1_at, geom2_at = layout
    model = mujoco.MjModel.from_xml_string(_PROBE)
    data = mujoco.MjData(model)
    data.time = 1234.5678
    mujoco.mj_forward(model, data)
    d = data._address
    for name in _CHECKED:
        field = getattr(data_t, name)
        if _value(d, field.offset, ctypes.c_void_p) != getattr(data, name).ctypes.data:
            return False
    if _value(d, data_t.time.offset, ctypes.c_double) != data.time:
        return False
    if data.ncon != 1 or _value(d, ncon_at, ctypes.c_int) != 1:
        return False
    contact = _value(d, contact_at, ctypes.c_void_p)
    geom1, geom2 = data.contact.geom1, data.contact.geom2
    return bool(
        contact is not None
        and geom1.strides[0] == size
        and contact + geom1_at == geom1.ctypes.data
        and contact + geom2_at == geom2.ctypes.data
        and {_value(contact, at, ctypes.c_int) for at in (geom1_at, geom2_at)} == {0, 1}
    )


__all__ = ["contact_layout"]

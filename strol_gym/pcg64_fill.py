"""``Generator.random(out=...)`` for many numpy ``PCG64`` generators in one compiled call.

A simulated person's candidates are 1,536 uniform draws from the person's own generator; for the
1,024 people of a vector env, numpy's per-call cost and its draw through a function pointer
were most of a correcting step. ``fill`` steps each generator's PCG64 (the 128-bit LCG and its
XSL-RR output, as numpy's ``pcg64.h``) inside one loop and writes the generator's state back,
so the doubles are numpy's, (x >> 11) · 2⁻⁵³, and the generator goes on where numpy's own
``random`` would have left it. It reads the state through the bit generator's
``ctypes.state_address``; ``addresses`` checks once per process, on a probe generator, that the
doubles and the state after them are numpy's (the layout of numpy's build), and answers None
for a generator that is not a ``PCG64``, or where the check fails: then the caller draws with
numpy. Generators' locks are not taken (an env steps in one thread).

This module imports numba: import it only when ``strol_gym.compiled.use_fast()``.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic as numba_intrinsic
from numba.np.random import _constants as ziggurat

intrinsic: Any = numba_intrinsic  # typed as in ik_kernel: numba checks the decorated calls
_jit: Any = njit(cache=True, nogil=True)

_MUL_HI = np.uint64(2549297995355413924)
_MUL_LO = np.uint64(4865540595714422341)
"""PCG's default 128-bit multiplier (numpy's ``PCG_DEFAULT_MULTIPLIER_128``), high and low."""


@intrinsic
def _mul_high(typingctx, a, b):
    """The high 64 bits of the 128-bit product of two uint64."""
    sig = types.uint64(types.uint64, types.uint64)

    def codegen(context, builder, signature, args):
        wide = ir.IntType(128)
        p = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        return builder.trunc(builder.lshr(p, ir.Constant(wide, 64)), ir.IntType(64))

    return sig, codegen


def _memory(bits: int) -> tuple[Any, Any]:
    """Intrinsics reading and writing the unsigned ``bits``-bit integer at an address."""
    kind: Any = {64: types.uint64, 32: types.uint32}[bits]

    @intrinsic
    def load(typingctx, address):
        def codegen(context, builder, signature, args):
            return builder.load(builder.inttoptr(args[0], ir.IntType(bits).as_pointer()))

        return kind(types.intp), codegen

    @intrinsic
    def store(typingctx, address, value):
        def codegen(context, builder, signature, args):
            builder.store(args[1], builder.inttoptr(args[0], ir.IntType(bits).as_pointer()))
            return context.get_dummy_value()

        return types.void(types.intp, kind), codegen

    return load, store


_load, _store = _memory(64)
_load32, _store32 = _memory(32)


_M4_HI, _M4_LO = np.uint64(17644330877953211035), np.uint64(15101941458738108273)
"""The multiplier to the 4th power (mod 2¹²⁸): four steps at once."""
_S4_HI, _S4_LO = np.uint64(6993546655799173219), np.uint64(9331354557045783068)
"""M³ + M² + M + 1 (mod 2¹²⁸): four steps add inc times this."""


@_jit
def _mul_add(lo, hi, m_lo, m_hi, a_lo, a_hi):
    """(hi, lo) · (m_hi, m_lo) + (a_hi, a_lo) mod 2¹²⁸, as (low, high) words."""
    low = lo * m_lo
    high = _mul_high(lo, m_lo) + hi * m_lo + lo * m_hi
    out_lo = low + a_lo
    carry = np.uint64(1) if out_lo < low else np.uint64(0)
    return out_lo, high + a_hi + carry


@_jit
def _output(lo, hi):
    """PCG64's XSL-RR output of a state (numpy's next_uint64)."""
    x, rot = hi ^ lo, hi >> np.uint64(58)
    return (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))


@_jit
def _double(lo, hi):
    """PCG64's output of a state as numpy's next_double takes it: (x >> 11) · 2⁻⁵³."""
    return np.float64(_output(lo, hi) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@_jit
def fill(states, out):
    """Row b of ``out`` (B, K) from the generator whose ``ctypes.state_address`` is
    ``states[b]``, as ``Generator.random(out=out[b])`` fills it; the states move on."""
    for b in range(states.shape[0]):
        fill_row(states[b], out[b])


@_jit
def fill_row(state, out):
    """``Generator.random(out=out)`` (``out`` 1-D) of the generator whose
    ``ctypes.state_address`` is ``state``.

    The LCG's states are the same integers numpy steps through; four chains four steps apart
    (multiplier M⁴, increment inc·(M³ + M² + M + 1)) run side by side, since one step waits
    for the last one's multiplication."""
    k = out.shape[0]
    blocks = k // 4 if k >= 8 else 0
    p = np.intp(_load(state))  # pcg64_state.pcg_state: state (low, high), inc (low, high)
    lo, hi, inc_lo, inc_hi = _load(p), _load(p + 8), _load(p + 16), _load(p + 24)
    done = 0
    if blocks:
        c4_lo, c4_hi = _mul_add(inc_lo, inc_hi, _S4_LO, _S4_HI, np.uint64(0), np.uint64(0))
        l0, h0 = _mul_add(lo, hi, _MUL_LO, _MUL_HI, inc_lo, inc_hi)
        l1, h1 = _mul_add(l0, h0, _MUL_LO, _MUL_HI, inc_lo, inc_hi)
        l2, h2 = _mul_add(l1, h1, _MUL_LO, _MUL_HI, inc_lo, inc_hi)
        l3, h3 = _mul_add(l2, h2, _MUL_LO, _MUL_HI, inc_lo, inc_hi)
        for blk in range(blocks):
            if blk:
                l0, h0 = _mul_add(l0, h0, _M4_LO, _M4_HI, c4_lo, c4_hi)
                l1, h1 = _mul_add(l1, h1, _M4_LO, _M4_HI, c4_lo, c4_hi)
                l2, h2 = _mul_add(l2, h2, _M4_LO, _M4_HI, c4_lo, c4_hi)
                l3, h3 = _mul_add(l3, h3, _M4_LO, _M4_HI, c4_lo, c4_hi)
            o = 4 * blk
            out[o] = _double(l0, h0)
            out[o + 1] = _double(l1, h1)
            out[o + 2] = _double(l2, h2)
            out[o + 3] = _double(l3, h3)
        lo, hi, done = l3, h3, 4 * blocks
    for i in range(done, k):
        lo, hi = _mul_add(lo, hi, _MUL_LO, _MUL_HI, inc_lo, inc_hi)
        out[i] = _double(lo, hi)
    _store(p, lo)
    _store(p + 8, hi)


_KI, _WI, _FI = ziggurat.ki_double, ziggurat.wi_double, ziggurat.fi_double
_NOR_R, _NOR_INV_R = ziggurat.ziggurat_nor_r, ziggurat.ziggurat_nor_inv_r
"""numpy's ziggurat tables and constants (``ziggurat_constants.h``), as numba copied them; the
check below compares the draws."""

# pcg64_state (numpy's pcg64.h): the LCG's address, then has_uint32 (int) and uinteger (uint32),
# the upper half of a 64-bit output kept for the next 32-bit draw.
_HAS32, _UINT32 = 8, 12


@_jit
def _next64(p):
    """numpy's next_uint64 of the LCG at ``p``: one step, its output; the state moves on."""
    lo, hi = _mul_add(_load(p), _load(p + 8), _MUL_LO, _MUL_HI, _load(p + 16), _load(p + 24))
    _store(p, lo)
    _store(p + 8, hi)
    return _output(lo, hi)


@_jit
def _next32(state):
    """numpy's next_uint32 of the ``pcg64_state`` at ``state``: the kept upper half of the
    last 64-bit draw, or a new draw's lower half (its upper half kept)."""
    if _load32(state + _HAS32):
        _store32(state + _HAS32, np.uint32(0))
        return _load32(state + _UINT32)
    x = _next64(np.intp(_load(state)))
    _store32(state + _HAS32, np.uint32(1))
    _store32(state + _UINT32, np.uint32(x >> np.uint64(32)))
    return np.uint32(x & np.uint64(0xFFFFFFFF))


@_jit
def _bounded(state, rng):
    """numpy's ``integers(0, rng + 1)`` for 0 < rng < 2³² − 1: Lemire's method on 32-bit draws
    (``buffered_bounded_lemire_uint32``)."""
    excl = np.uint64(rng) + np.uint64(1)
    m = np.uint64(_next32(state)) * excl
    left = m & np.uint64(0xFFFFFFFF)
    if left < excl:
        threshold = (np.uint64(0xFFFFFFFF) - np.uint64(rng)) % excl
        while left < threshold:
            m = np.uint64(_next32(state)) * excl
            left = m & np.uint64(0xFFFFFFFF)
    return np.int64(m >> np.uint64(32))


@_jit
def _next_double(p):
    return np.float64(_next64(p) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@_jit
def _normal(p):
    """numpy's ``random_standard_normal`` (the 256-step ziggurat, its tables as numba's copy
    of them) on the LCG at ``p``."""
    while True:
        r = _next64(p)
        idx = np.intp(r & np.uint64(0xFF))
        r >>= np.uint64(8)
        rabs = (r >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF)
        x = np.float64(rabs) * _WI[idx]
        if r & np.uint64(1):
            x = -x
        if rabs < _KI[idx]:
            return x
        if idx == 0:
            while True:
                xx = -_NOR_INV_R * np.log1p(-_next_double(p))
                yy = -np.log1p(-_next_double(p))
                if yy + yy > xx * xx:
                    if (rabs >> np.uint64(8)) & np.uint64(1):
                        return -(_NOR_R + xx)
                    return _NOR_R + xx
        elif (_FI[idx - 1] - _FI[idx]) * _next_double(p) + _FI[idx] < np.exp(-0.5 * x * x):
            return x


@_jit
def mixture(states, k, idx, z):
    """From the generator whose ``ctypes.state_address`` is ``states[b]``: ``idx[b]`` as
    ``integers(0, k)`` (0 < k < 2³²), then row b of ``z`` (B, d) as ``standard_normal(d)``;
    the states move on as numpy's would."""
    for b in range(states.shape[0]):
        idx[b] = 0 if k == 1 else _bounded(states[b], np.uint64(k - 1))
        normals(states[b], z[b])


@_jit
def normals(state, out):
    """``Generator.standard_normal(out=out)`` (``out`` 1-D) of the generator whose
    ``ctypes.state_address`` is ``state``."""
    p = np.intp(_load(state))
    for j in range(out.shape[0]):
        out[j] = _normal(p)


def addresses(
    rngs: Sequence[np.random.Generator], kernels: tuple[str, ...] = ("fill",)
) -> np.ndarray | None:
    """The generators' state addresses for ``kernels`` ("fill": ``fill`` and ``fill_row``;
    "mixture": ``mixture`` and ``normals``), or None: one is not a numpy ``PCG64``, or a
    kernel does not give numpy's draws in this process."""
    if not all(_agrees() if kernel == "fill" else _mixture_agrees() for kernel in kernels):
        return None
    bits = [rng.bit_generator for rng in rngs]
    for one in bits:
        if type(one) is not np.random.PCG64:
            return None
    return np.array([one.ctypes.state_address for one in bits], dtype=np.intp)


@functools.cache
def _agrees() -> bool:
    """``fill`` against ``Generator.random`` on probe generators: the same doubles and states?"""
    try:
        ours = [np.random.Generator(np.random.PCG64(seed)) for seed in (0, 12345)]
        numpys = [np.random.Generator(np.random.PCG64(seed)) for seed in (0, 12345)]
        got = np.empty((2, 1000))
        states = np.array([g.bit_generator.ctypes.state_address for g in ours], dtype=np.intp)
        fill(states, got)
        fill(states, got[:, :3])
        fill(states, got[:, 3:13])
        want = np.stack([g.random(1000) for g in numpys])
        want[:, :3] = np.stack([g.random(3) for g in numpys])
        want[:, 3:13] = np.stack([g.random(10) for g in numpys])
        same_states = all(
            a.bit_generator.state == b.bit_generator.state
            for a, b in zip(ours, numpys, strict=True)
        )
        return same_states and got.tobytes() == want.tobytes()
    except Exception:  # a numba that cannot compile it here: numpy draws
        return False


@functools.cache
def _mixture_agrees() -> bool:
    """``mixture`` against ``integers`` and ``standard_normal`` on probe generators, rounds of
    them with a ``random`` between (the 32-bit draw's kept half carries over), and 20,000
    normals of one (the ziggurat's rare paths): the same numbers and states?"""
    try:
        seeds = range(200)
        ours = [np.random.Generator(np.random.PCG64(seed)) for seed in seeds]
        numpys = [np.random.Generator(np.random.PCG64(seed)) for seed in seeds]
        states = np.array([g.bit_generator.ctypes.state_address for g in ours], dtype=np.intp)
        same = True
        for k, d in ((2, 2), (3, 1), (7, 3), (1, 2), (2, 2)):
            idx, z = np.empty(len(ours), dtype=np.int64), np.empty((len(ours), d))
            mixture(states, k, idx, z)
            want_idx = np.array([g.integers(0, k) for g in numpys], dtype=np.int64)
            want_z = np.stack([g.standard_normal(d) for g in numpys])
            same = same and idx.tobytes() == want_idx.tobytes() and z.tobytes() == want_z.tobytes()
            for a, b in zip(ours, numpys, strict=True):
                same = same and a.random() == b.random()
        one, other = (
            np.random.Generator(np.random.PCG64(5)),
            np.random.Generator(np.random.PCG64(5)),
        )
        z = np.empty((1, 20000))
        mixture(np.array([one.bit_generator.ctypes.state_address], dtype=np.intp), 1, idx[:1], z)
        same = same and z[0].tobytes() == other.standard_normal(20000).tobytes()
        return same and all(
            a.bit_generator.state == b.bit_generator.state
            for a, b in zip([*ours, one], [*numpys, other], strict=True)
        )
    except Exception:  # a numba that cannot compile it here: numpy draws
        return False

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


@intrinsic
def _load(typingctx, address):
    """The uint64 at ``address``."""
    sig = types.uint64(types.intp)

    def codegen(context, builder, signature, args):
        return builder.load(builder.inttoptr(args[0], ir.IntType(64).as_pointer()))

    return sig, codegen


@intrinsic
def _store(typingctx, address, value):
    """Writes uint64 ``value`` at ``address``."""
    sig = types.void(types.intp, types.uint64)

    def codegen(context, builder, signature, args):
        builder.store(args[1], builder.inttoptr(args[0], ir.IntType(64).as_pointer()))
        return context.get_dummy_value()

    return sig, codegen


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
def _double(lo, hi):
    """PCG64's XSL-RR output of a state, as numpy's next_double takes it: (x >> 11) · 2⁻⁵³."""
    x, rot = hi ^ lo, hi >> np.uint64(58)
    x = (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))
    return np.float64(x >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@_jit
def fill(states, out):
    """Row b of ``out`` (B, K) from the generator whose ``ctypes.state_address`` is
    ``states[b]``, as ``Generator.random(out=out[b])`` fills it; the states move on.

    The LCG's states are the same integers numpy steps through; four chains four steps apart
    (multiplier M⁴, increment inc·(M³ + M² + M + 1)) run side by side, since one step waits
    for the last one's multiplication."""
    k = out.shape[1]
    blocks = k // 4 if k >= 8 else 0
    for b in range(states.shape[0]):
        p = np.intp(_load(states[b]))  # pcg64_state.pcg_state: state (low, high), inc (low, high)
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
                out[b, o] = _double(l0, h0)
                out[b, o + 1] = _double(l1, h1)
                out[b, o + 2] = _double(l2, h2)
                out[b, o + 3] = _double(l3, h3)
            lo, hi, done = l3, h3, 4 * blocks
        for i in range(done, k):
            lo, hi = _mul_add(lo, hi, _MUL_LO, _MUL_HI, inc_lo, inc_hi)
            out[b, i] = _double(lo, hi)
        _store(p, lo)
        _store(p + 8, hi)


def addresses(rngs: Sequence[np.random.Generator]) -> np.ndarray | None:
    """The generators' state addresses for ``fill``, or None: one is not a numpy ``PCG64``, or
    ``fill`` does not give numpy's doubles in this process."""
    if not _agrees():
        return None
    out = np.empty(len(rngs), dtype=np.intp)
    for b, rng in enumerate(rngs):
        bits = rng.bit_generator
        if type(bits) is not np.random.PCG64:
            return None
        out[b] = bits.ctypes.state_address
    return out


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

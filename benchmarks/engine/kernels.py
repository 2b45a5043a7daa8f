"""Which floating-point kernels this process computes with: the provenance of a results folder.

Our runs are bit-identical on one machine (``--jobs``, resume, Ray), but not across machines:
OpenBLAS picks its kernel per CPU (or from ``OPENBLAS_CORETYPE``), numpy dispatches its SIMD
loops per CPU, and torch picks its ATen kernels (``ATEN_CPU_CAPABILITY``) and uses MKL for BLAS.
Each can change the last bits of a number, and a chaotic episode amplifies them. So meta.json,
every unit's record file and every session name the kernels that made them, and a folder whose
records come from different ones says so (docs/reproducibility.md).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import glob
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

ENV_VARS = (
    "OPENBLAS_CORETYPE",
    "ATEN_CPU_CAPABILITY",
    "MKL_ENABLE_INSTRUCTIONS",
    "MKL_CBWR",
    "NPY_DISABLE_CPU_FEATURES",
)
"""Environment variables that choose kernels; recorded when set."""
LABEL_KEYS = ("openblas", "numpy_simd", "torch_cpu", "torch_blas")
"""The fields that make up a kernel label (the environment variables act through them)."""


def _openblas_libraries() -> list[str]:
    """Paths of the OpenBLAS builds numpy may have loaded: its wheel's own, then any mapped."""
    import numpy as np

    root = Path(np.__file__).resolve().parent
    found = glob.glob(str(root.parent / "numpy.libs" / "*openblas*"))
    found += glob.glob(str(root / ".dylibs" / "*openblas*"))
    with contextlib.suppress(OSError):
        for line in Path("/proc/self/maps").read_text().splitlines():
            path = line.split()[-1] if len(line.split()) >= 6 else ""
            if "openblas" in Path(path).name.lower():
                found.append(path)
    return list(dict.fromkeys(found))


def openblas_core() -> str | None:
    """The kernel OpenBLAS runs (e.g. "Haswell"), asked of the library itself; None without one."""
    for path in _openblas_libraries():
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in ("scipy_", ""):
            for suffix in ("64_", ""):
                fn = getattr(lib, f"{prefix}openblas_get_corename{suffix}", None)
                if fn is not None:
                    fn.restype = ctypes.c_char_p
                    return fn().decode()
    return None


def numpy_simd() -> str:
    """numpy's highest SIMD target enabled on this CPU (its dispatched loops use it)."""
    try:
        # private: numpy's stubs do not declare it
        from numpy._core import _multiarray_umath as umath  # type: ignore[attr-defined]
    except ImportError:  # numpy < 2
        from numpy.core import _multiarray_umath as umath
    features = umath.__cpu_features__
    enabled = [f for f in umath.__cpu_dispatch__ if features.get(f)]
    return (enabled or list(umath.__cpu_baseline__) or ["none"])[-1]


def _torch() -> dict[str, Any]:
    try:
        import torch
    except ImportError:
        return {"torch_cpu": None, "torch_blas": None}
    blas = None
    if torch.backends.mkl.is_available():
        m = re.search(r"Math Kernel Library Version (\S+)", torch.__config__.show())
        blas = f"mkl-{m.group(1)}" if m else "mkl"
    else:
        m = re.search(r"BLAS_INFO=(\w+)", torch.__config__.show())
        blas = m.group(1) if m else None
    return {"torch_cpu": torch.backends.cpu.get_cpu_capability(), "torch_blas": blas}


@functools.cache
def float_kernels() -> dict[str, Any]:
    """This process's kernels: OpenBLAS's core, numpy's SIMD target, torch's CPU capability and
    BLAS, and the environment variables that chose them. Fixed for the life of a process."""
    out: dict[str, Any] = {"openblas": openblas_core(), "numpy_simd": numpy_simd(), **_torch()}
    out["env"] = {v: os.environ[v] for v in ENV_VARS if v in os.environ}
    return out


def kernel_label(kernels: Mapping[str, Any] | None = None) -> str:
    """One line naming the kernels, e.g. "openblas=Haswell numpy=X86_V3 torch=AVX2 blas=mkl-…"."""
    k = float_kernels() if kernels is None else kernels
    names = {"openblas": "openblas", "numpy_simd": "numpy", "torch_cpu": "torch"}
    names["torch_blas"] = "torch-blas"
    return " ".join(f"{names[key]}={k.get(key)}" for key in LABEL_KEYS)


def mixed_kernels_message(path: Path, by_label: Mapping[str, list[str]], now: str) -> str | None:
    """One line for a folder whose records came from other kernels than ``now`` (or from
    several): which units came from which; None when every record matches ``now``."""
    if not by_label or set(by_label) == {now}:
        return None
    parts = []
    for label, units in sorted(by_label.items(), key=lambda kv: -len(kv[1])):
        shown = ", ".join(units[:3]) + (", …" if len(units) > 3 else "")
        parts.append(f"{len(units)} unit(s) under [{label}] ({shown})")
    return (
        f"warning: {path} mixes floating-point kernels: {'; '.join(parts)}; this process runs "
        f"[{now}]. Means and verdicts hold across kernels, per-run numbers may differ "
        "(docs/reproducibility.md); use a fresh --out for a single-kernel folder."
    )

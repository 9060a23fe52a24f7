"""The machine a run trains on, as far as it decides the run's floating-point results.

A resume is exact on the machine that wrote the checkpoint (`exact_resume`). Elsewhere the
same code can compute other bits: the numerical libraries pick their kernels by the CPU's
vector instructions, and their versions change the kernels. A run resumed on another
machine goes on from its checkpoint exactly, but its course from there can differ from the
one the first machine would have trained. So each checkpoint records its machine, a resume
on a different one says so, and the run's outcome lists the machines it trained on.
"""

from __future__ import annotations

import importlib.metadata
import pathlib
import platform
import re

#: The packages whose kernels compute a run: the physics, the networks, the sampling.
LIBRARIES = ("numpy", "mujoco", "torch", "jax", "jaxlib", "stable_baselines3", "sbx-rl")
#: The CPU flags that name vector instruction sets, which those libraries dispatch on.
_VECTOR_FLAG = re.compile(r"^(sse|ssse|avx|fma|f16c|amx|asimd|sve|neon)")
_CPUINFO = pathlib.Path("/proc/cpuinfo")


def fingerprint() -> dict:
    """{"cpu", "vector_isa", "python", "libraries"} of this machine: its CPU's model name,
    the vector instruction sets it offers (None where /proc/cpuinfo does not say), and the
    versions of Python and of `LIBRARIES` (None for one not installed)."""
    fields = _cpuinfo()
    flags = _flags(fields)
    return {"cpu": fields.get("model name", platform.processor() or platform.machine()),
            "vector_isa": (None if flags is None else
                           sorted(flag for flag in flags if _VECTOR_FLAG.match(flag))),
            "python": platform.python_version(),
            "libraries": {name: _version(name) for name in LIBRARIES}}


def bf16_units() -> bool | None:
    """Whether this CPU multiplies in bfloat16 (AVX512-BF16, AMX-BF16, Arm's BF16): without
    them torch emulates bf16 (`precision`); None where /proc/cpuinfo does not say."""
    flags = _flags(_cpuinfo())
    return bool(set(flags) & {"avx512_bf16", "amx_bf16", "bf16"}) if flags else None


def _cpuinfo() -> dict[str, str]:
    """/proc/cpuinfo's fields ({} without it): every processor's lines alike, the last
    one's stand."""
    if not _CPUINFO.is_file():
        return {}
    fields = dict(line.split(":", 1) for line in _CPUINFO.read_text().splitlines()
                  if ":" in line)
    return {key.strip(): value.strip() for key, value in fields.items()}


def _flags(fields: dict[str, str]) -> list[str] | None:
    """The CPU's flags (x86's `flags`, Arm's `Features`) among `_cpuinfo`'s fields; None
    where they are not listed."""
    listed = fields.get("flags", fields.get("Features"))
    return None if listed is None else listed.split()


def _version(package: str) -> str | None:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def differences(before: dict, now: dict) -> list[str]:
    """What differs between two fingerprints, in words ([] where nothing does)."""
    said = []
    if before.get("cpu") != now.get("cpu"):
        said.append(f"CPU {before.get('cpu')!r} then, {now.get('cpu')!r} now")
    isa_before, isa_now = before.get("vector_isa"), now.get("vector_isa")
    if isa_before != isa_now:
        if isa_before is None or isa_now is None:
            said.append("vector instruction sets unknown on one of them")
        else:
            gone, added = sorted(set(isa_before) - set(isa_now)), sorted(
                set(isa_now) - set(isa_before))
            said.append("vector instruction sets" + (f" without {', '.join(gone)}" if gone
                                                     else "") +
                        (" and" if gone and added else "") +
                        (f" with {', '.join(added)}" if added else "") + " now")
    if before.get("python") != now.get("python"):
        said.append(f"Python {before.get('python')} then, {now.get('python')} now")
    libraries_before, libraries_now = before.get("libraries", {}), now.get("libraries", {})
    for name in sorted(set(libraries_before) | set(libraries_now)):
        if libraries_before.get(name) != libraries_now.get(name):
            said.append(f"{name} {libraries_before.get(name) or 'absent'} then, "
                        f"{libraries_now.get(name) or 'absent'} now")
    return said


def another_machine(changed: list[str]) -> str:
    """What a change of machine means for a run resumed on it, said alike by a resumed run
    and by the campaigns' logs of their machines: "another machine (what differs): ..."."""
    return (f"another machine ({'; '.join(changed)}): a resume there is exact, but from there "
            "a run's floating-point results, and so its course, can differ from the ones the "
            "machine before would have computed")

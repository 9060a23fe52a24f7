"""What a run records of its machine (`training.machine`), read from fixed inputs."""

from __future__ import annotations

import pytest

from franka_composer.training import machine

CPUINFO = """processor\t: 0
vendor_id\t: AuthenticAMD
model name\t: AMD EPYC 9R14
flags\t\t: fpu sse sse2 ssse3 sse4_1 sse4_2 avx avx2 fma f16c avx512f avx512_bf16 hypervisor

processor\t: 1
vendor_id\t: AuthenticAMD
model name\t: AMD EPYC 9R14
flags\t\t: fpu sse sse2 ssse3 sse4_1 sse4_2 avx avx2 fma f16c avx512f avx512_bf16 hypervisor
"""


def test_the_fingerprint_keeps_the_cpu_and_its_vector_instruction_sets_only(tmp_path,
                                                                            monkeypatch):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text(CPUINFO)
    monkeypatch.setattr(machine, "_CPUINFO", cpuinfo)
    found = machine.fingerprint()
    assert found["cpu"] == "AMD EPYC 9R14"
    assert found["vector_isa"] == ["avx", "avx2", "avx512_bf16", "avx512f", "f16c", "fma",
                                   "sse", "sse2", "sse4_1", "sse4_2", "ssse3"]
    assert set(found["libraries"]) == set(machine.LIBRARIES)
    assert found["libraries"]["numpy"] == __import__("numpy").__version__


def test_without_cpuinfo_the_vector_instruction_sets_are_unknown(tmp_path, monkeypatch):
    monkeypatch.setattr(machine, "_CPUINFO", tmp_path / "absent")
    found = machine.fingerprint()
    assert found["vector_isa"] is None and found["cpu"]


@pytest.mark.parametrize("cpuinfo, units", [
    (CPUINFO, True),  # Zen 4: AVX512-BF16.
    (CPUINFO.replace(" avx512f avx512_bf16", ""), False),  # AVX2 only: torch emulates bf16.
    ("flags\t\t: sse avx2 amx_bf16 amx_tile\n", True),
    ("processor\t: 0\nFeatures\t: fp asimd sve bf16 i8mm\n", True),  # Arm Neoverse V1.
    ("processor\t: 0\nFeatures\t: fp asimd\n", False),
    ("processor\t: 0\n", None),
    (None, None)])
def test_bf16_units_are_read_from_the_cpus_flags(tmp_path, monkeypatch, cpuinfo, units):
    path = tmp_path / "cpuinfo"
    if cpuinfo is not None:
        path.write_text(cpuinfo)
    monkeypatch.setattr(machine, "_CPUINFO", path)
    assert machine.bf16_units() is units


BASE = {"cpu": "AMD EPYC", "vector_isa": ["avx2", "avx512f", "fma"], "python": "3.11.7",
        "libraries": {"numpy": "2.4.6", "torch": "2.13.0+cpu", "sbx-rl": "0.28.0"}}


@pytest.mark.parametrize("change, said", [
    ({}, []),
    ({"cpu": "Intel Xeon"}, ["CPU 'AMD EPYC' then, 'Intel Xeon' now"]),
    ({"vector_isa": ["avx2", "fma"]}, ["vector instruction sets without avx512f now"]),
    ({"vector_isa": ["avx2", "avx512_bf16", "fma"]},
     ["vector instruction sets without avx512f and with avx512_bf16 now"]),
    ({"vector_isa": None}, ["vector instruction sets unknown on one of them"]),
    ({"python": "3.12.1"}, ["Python 3.11.7 then, 3.12.1 now"]),
    ({"libraries": {"numpy": "2.4.6", "torch": "2.12.0", "jax": "0.10.2"}},
     ["jax absent then, 0.10.2 now", "sbx-rl 0.28.0 then, absent now",
      "torch 2.13.0+cpu then, 2.12.0 now"]),
])
def test_differences_name_what_changed(change, said):
    assert machine.differences(BASE, {**BASE, **change}) == said
    # A step recorded beside the fingerprint is not a difference.
    assert machine.differences({"from_steps": 0, **BASE}, {**BASE, **change}) == said

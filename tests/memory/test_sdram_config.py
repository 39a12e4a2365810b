"""SDRAM parameters: the built-in machines' [memory] tables parse, bad values name the key."""

from __future__ import annotations

import pytest

from hwsim.core.errors import InputError
from hwsim.memory import MemoryConfig, SdramConfig, parse_memory
from hwsim.run.fidelity import resolve_arch

pytestmark = pytest.mark.model


@pytest.mark.parametrize("name", ["volumepro500", "em-cube", "volumepro1000"])
def test_builtin_memory_tables_parse(name):
    arch = resolve_arch(name)
    mem = parse_memory(arch.memory, source=arch.source)
    assert mem.skew == "miniblock" and mem.sdram.burst_length == 8
    # One voxel per pipeline per clock: module beats per clock cover the pipelines.
    assert mem.modules * mem.sdram.data_rate / mem.sdram.clock_ratio >= arch.pipelines


def test_volumepro500_table_is_pc133_class_at_125_mhz():
    """architectures.md 9.1/9.3: burst 8, CAS 2-3 at 125 MHz, 4 banks."""
    mem = parse_memory(resolve_arch("volumepro500").memory, source="vp500")
    d = mem.sdram
    assert (mem.modules, d.banks, d.burst_length, d.data_rate) == (4, 4, 8, 1)
    assert d.cas_latency in (2, 3)
    assert mem.modules * d.words * d.word_bits // 8 == 128 * 2**20  # the 128 MB board [V]


def test_em_cube_holds_exactly_256_cubed_16_bit():
    """4 x 64 Mbit SDRAM [V] = 256^3 x 16 bit [I]."""
    mem = parse_memory(resolve_arch("em-cube").memory, source="em-cube")
    assert mem.sdram.words * mem.sdram.word_bits == 64 * 2**20
    assert mem.modules * mem.sdram.words == 256**3


def test_empty_table_gives_the_defaults():
    assert parse_memory({}, source="x.toml") == MemoryConfig()


@pytest.mark.parametrize(
    ("table", "key", "allowed"),
    [
        ({"banks": 0}, "memory.banks", "1 .. 64"),
        ({"t_rcd": -1}, "memory.t_rcd", "0 .. 64"),
        ({"cas_latency": 2.5}, "memory.cas_latency", "1 .. 16"),
        ({"page_policy": "lazy"}, "memory.page_policy", "open, closed"),
        ({"skew": "diagonal"}, "memory.skew", "cube4, miniblock, block"),
        ({"clock_ratio": 0}, "memory.clock_ratio", "0.015625 .. 64"),
        ({"t_rc": 3}, "memory.t_rc", ">= 7"),
        ({"burst_length": 3}, "memory.columns", "k * burst_length"),
        ({"t_refi": 10}, "memory.t_refi", "0 (off) or >"),
        ({"data_rate": 2, "burst_length": 1, "columns": 1}, "memory.burst_length", "even"),
        ({"cas": 2}, "memory.cas", "cas_latency"),
    ],
)
def test_bad_values_name_file_key_and_range(table, key, allowed):
    with pytest.raises(InputError) as info:
        parse_memory(table, source="arch.toml")
    text = str(info.value)
    assert text.startswith(f"arch.toml: {key}:") and allowed in text and "\n" not in text


def test_dataclass_refuses_inconsistent_timings():
    with pytest.raises(ValueError, match="t_rc"):
        SdramConfig(t_ras=6, t_rp=3, t_rc=8)
    with pytest.raises(ValueError, match="queue_depth"):
        SdramConfig(queue_depth=0)


def test_derived_quantities():
    d = SdramConfig(data_rate=2, burst_length=8)
    assert d.burst_cycles == 4 and d.read_to_precharge == 4 and d.peak_words_per_cycle == 2
    assert SdramConfig().words == 4 * 8192 * 512


def test_clock_conversion_rounds_up():
    d = SdramConfig(clock_ratio=1.5)  # memory at 1.5x the pipeline clock
    assert d.to_pipeline_cycles([0, 3, 4]).tolist() == [0, 2, 3]
    assert d.to_memory_cycles([0, 1, 2]).tolist() == [0, 2, 3]
    assert SdramConfig().to_pipeline_cycles(17).item() == 17

"""Every published figure says what kind of evidence it is, and a label that the file's own
arithmetic contradicts is refused when the file is read (hwsim.spec.published)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hwsim.core.errors import InputError
from hwsim.run.fidelity import builtin_archs, resolve_arch
from hwsim.spec.published import EVIDENCE, Scenario, parse_published, restates_peak
from hwsim.studies.figures import published_figures

pytestmark = pytest.mark.system

ARCH = """schema = 1
name = "tiny"
[pipeline]
order = "slice-parallel"
count = {count}
clock_hz = {clock}
[limits]
max_volume = [1024, 1024, 1024]
[published]
{published}
"""


def _load(tmp_path, published: str, count: int = 4, clock: float = 125e6):
    path = tmp_path / "tiny.toml"
    path.write_text(ARCH.format(count=count, clock=clock, published=published))
    return resolve_arch(str(path))


@pytest.mark.parametrize("name", sorted(builtin_archs()))
def test_every_built_in_figure_is_labelled(name):
    arch = builtin_archs()[name]
    for fig in published_figures(arch):
        assert fig.evidence in EVIDENCE
        assert bool(fig.fitted_from) == (fig.evidence == "fitted") or fig.evidence == "peak"
        if fig.evidence == "prediction":
            assert not restates_peak(
                fig.metric, fig.value, fig.scenario, arch.peak_samples_per_second
            )


def test_the_built_in_predictions_cite_their_sources_on_two_families():
    """Issue 30: prediction rows from stated or measured figures on >= 2 families."""
    rows = [
        (arch.family, fig)
        for arch in builtin_archs().values()
        for fig in published_figures(arch)
        if fig.evidence == "prediction"
    ]
    assert len(rows) >= 3
    assert len({family for family, _ in rows}) >= 2
    for _, fig in rows:  # a [V] source: in the figure's own citation or the file's note
        assert "[V]" in fig.source or "[V]" in fig.note or fig.kind == "stated", fig


@pytest.mark.parametrize(
    ("published", "message"),
    [
        ("fps_256 = 10.0", "published.evidence.fps_256: is required"),
        ('fps_256 = 10.0\nevidence = { fps_256 = "validated" }', "unknown value 'validated'"),
        ('fps_256 = 10.0\nevidence = { fps_256 = "fitted" }', "must name the keys set from it"),
        (
            'fps_256 = 10.0\nevidence = { fps_256 = "fitted" }\n'
            'fitted_from = { fps_256 = ["pipeline.speed"] }',
            "'pipeline.speed' is not a key of this file",
        ),
        (
            'fps_256 = 10.0\nevidence = { fps_256 = "prediction" }\n'
            'fitted_from = { fps_256 = ["pipeline.count"] }',
            "a prediction has no fitted keys",
        ),
        (
            'fps_256 = 10.0\nevidence = { fps_256 = "prediction", fps_512 = "peak" }',
            "published.evidence.fps_512: unknown key",
        ),
        ('fps_x = 10.0\nevidence = { fps_x = "peak" }', "published.fps_x: unknown figure"),
        ('fps_256 = "fast"\nevidence = { fps_256 = "peak" }', "must be a number"),
        (
            '[[published.measured]]\nname = "a"\nfps = 3.0\nvolume = [64, 64, 32]\n'
            'kind = "measured"\nsource = "[V] x"',
            "published.measured[0].volume: invalid",
        ),
        (
            '[[published.measured]]\nname = "a"\nfps = 3.0\nseconds = 1.0\n'
            'volume = [64, 64, 64]\nkind = "measured"\nsource = "[V] x"',
            "exactly one of fps, seconds, samples_per_second",
        ),
    ],
)
def test_bad_labels_are_one_line_errors_naming_the_key(tmp_path, published, message):
    with pytest.raises(InputError, match="tiny.toml") as err:
        _load(tmp_path, published)
    assert message in str(err.value) and "\n" not in str(err.value)


PEAK = 4 * 125e6


@settings(max_examples=60, deadline=None)
@given(
    metric=st.sampled_from(["fps", "seconds", "samples_per_second"]),
    n=st.sampled_from([64, 128, 256, 512]),
    off=st.floats(-0.0099, 0.0099),
)
def test_a_figure_that_restates_pipelines_x_clock_is_never_a_prediction(metric, n, off):
    """Whatever figure and size: a value within 1 % of P x f restated is refused as a
    prediction and accepted as peak; 2 % away it may be a prediction."""
    rate = PEAK * (1 + off)
    value = {"fps": rate / n**3, "seconds": n**3 / rate, "samples_per_second": rate}[metric]
    key = {"fps": f"fps_{n}", "seconds": f"seconds_{n}", "samples_per_second": "samples_per_second"}
    table = {key[metric]: value, "evidence": {key[metric]: "prediction"}}
    if metric == "samples_per_second":
        table[f"fps_{n}"] = 1.0  # the scenario size of samples_per_second
        table["evidence"][f"fps_{n}"] = "prediction"
    with pytest.raises(InputError, match="restated"):
        parse_published(table, source="t.toml", peak_samples_per_second=PEAK)
    table["evidence"][key[metric]] = "peak"
    parse_published(table, source="t.toml", peak_samples_per_second=PEAK)
    far = {"fps": 1.03, "seconds": 1 / 1.03, "samples_per_second": 1.03}[metric]
    table[key[metric]] = value * far
    table["evidence"][key[metric]] = "prediction"
    parse_published(table, source="t.toml", peak_samples_per_second=PEAK)


def test_supersampled_or_terminated_scenarios_are_not_peak_restatements():
    scenario = Scenario((256, 256, 256), supersampling=2.0)
    assert not restates_peak("fps", PEAK / 256**3, scenario, PEAK)
    assert restates_peak("fps", PEAK / 256**3, Scenario((256, 256, 256)), PEAK)


def test_a_measured_figure_keeps_its_scenario_and_source(tmp_path):
    arch = _load(
        tmp_path,
        '[[published.measured]]\nname = "vp_ss2"\nfps = 14.0\nvolume = [128, 128, 128]\n'
        'supersampling = 2.0\nimage = [64, 48]\nkind = "measured"\nsource = "[V] a paper"',
    )
    (fig,) = published_figures(arch)
    assert fig.evidence == "prediction" and fig.kind == "measured"
    assert fig.scenario.image == (64, 48) and fig.scenario.supersampling == 2.0
    assert fig.size == 128 and not fig.scenario.dense
    assert "supersampling 2" in fig.scenario.text() and "image 64x48" in fig.scenario.text()

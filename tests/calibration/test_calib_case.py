"""Case definitions: TOML parsing, one-line validation errors naming the field, Table 2 presets."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest

from scm_core.calibration import CaseDefinition, CaseError, load_case, preset_case
from scm_core.calibration.presets import PRESETS, preset_cost, stage_runs
from scm_core.inference import TABLE2_NOMINAL, TMCMCSettings, table2_prior
from scm_core.inference.tmcmc.moves import form_defaults

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"

BASE = {
    "name": "t",
    "seed": 3,
    "parameters": {
        "phi": {"dist": "normal", "mean": 30.0, "sd": 5.7, "lower": 11.5, "upper": 37.3},
        "J": {"dist": "uniform", "lower": 0.001, "upper": 0.1},
        "sigma_F": {"dist": "uniform", "lower": 0.0, "upper": 5.0},
    },
    "nominal": {"sigma_T": 0.5, "sigma_z": 0.001, "R": 0.125},
    "simulator": {"duration": 12.0, "offset_F": 6.0, "offset_T": 6.0, "offset_z": 6.0},
}

TOML = """
name = "toml case"
seed = 5
likelihood = "gaussian"
responses = ["F", "z"]

[parameters]
k_phi = { dist = "log_uniform", lower = 1e6, upper = 1e8 }
n = { dist = "normal", mean = 1.1, sd = 0.2, lower = 0.8, upper = 2.0 }
sigma_z = { dist = "uniform", lower = 0.0, upper = 0.005 }

[nominal]
sigma_F = 2.0
phi = 27.0

[simulator]
dx = 0.01

[sampler]
n_samples = 300
moves = "leader"
max_stages = 12

[data]
files = ["logs/a.csv", "/abs/b.csv"]
offset = 30.0
"""


def build(**changes):
    doc = copy.deepcopy(BASE)
    for key, value in changes.items():
        if value is None:
            doc.pop(key, None)
        else:
            doc[key] = value
    return CaseDefinition.from_dict(doc)


def test_cmu_case_takes_k_star_from_the_plate_tests_as_a_log_normal_prior() -> None:
    from scipy import stats

    case = load_case(EXAMPLES / "cmu_smooth.toml")
    k = case.prior().dists["k_phi"]
    assert k.kind == "log_normal" and (k.median, k.factor) == (8.0e6, 2.0)
    # the plate tests' value is the median, one geometric sd a factor of two (the truncation
    # at 1e8, 3.6 geometric sd above, moves the quantiles by ~1e-4)
    assert k.ppf(0.5) == pytest.approx(8.0e6, rel=1e-3)
    assert k.ppf(stats.norm.cdf(1.0)) == pytest.approx(16.0e6, rel=1e-3)
    assert case.to_dict()["parameters"]["k_phi"]["dist"] == "log_normal"
    again = CaseDefinition.from_dict(case.to_dict(), EXAMPLES)
    assert again.fingerprint() == case.fingerprint()


def test_toml_case_parses_in_order(tmp_path: Path) -> None:
    (tmp_path / "c.toml").write_text(TOML)
    case = load_case(tmp_path / "c.toml")
    assert case.parameter_names == ("k_phi", "n", "sigma_z")
    assert case.likelihood == "gaussian" and case.responses == ("F", "z")
    assert case.sampler.n_samples == 300 and case.tmcmc_settings().moves == "leader"
    assert case.tmcmc_settings().max_stages == 12
    assert case.data_paths() == [tmp_path / "logs" / "a.csv", Path("/abs/b.csv")]
    assert case.sigma_spec() == {"F": ("fixed", 2.0), "z": ("parameter", 2)}
    prior = case.prior()
    assert prior.names == case.parameter_names
    assert prior.dists["k_phi"].kind == "log_uniform"
    again = CaseDefinition.from_dict(case.to_dict(), tmp_path)
    assert again.to_dict() == case.to_dict()
    assert again.fingerprint() == case.fingerprint()


def test_fingerprint_ignores_what_does_not_change_samples() -> None:
    case = build()
    same = case.with_changes(data={"files": ["x.csv"]}, sampler={"batch_size": 7, "max_stages": 3})
    assert same.fingerprint() == case.fingerprint()
    assert case.with_changes(seed=4).fingerprint() != case.fingerprint()
    assert case.with_changes(sampler={"n_samples": 99}).fingerprint() != case.fingerprint()
    assert case.with_changes(data={"offset": 30.0}).fingerprint() != case.fingerprint()


@pytest.mark.parametrize(
    ("changes", "needle"),
    [
        (
            {"parameters": {"k_cc": {"dist": "uniform", "lower": 0, "upper": 1}}},
            "parameters.k_cc: unknown parameter 'k_cc'",
        ),
        (
            {"parameters": {"J": {"dist": "uniform", "lower": 0.1, "upper": 0.001}}},
            "parameters.J: 'upper' (0.001) must be greater than 'lower' (0.1)",
        ),
        (
            {"parameters": {"J": {"dist": "normal", "mean": 0.01, "lower": 0.0, "upper": 1.0}}},
            "parameters.J: normal prior is missing 'sd'",
        ),
        (
            {
                "parameters": {
                    "K": {"dist": "log_normal", "median": 3e7, "lower": 1e6, "upper": 1e9}
                }
            },
            "parameters.K: log_normal prior is missing 'factor'",
        ),
        (
            {
                "parameters": {
                    "K": {
                        "dist": "log_normal",
                        "median": 3e7,
                        "factor": 0.5,
                        "lower": 1e6,
                        "upper": 1e9,
                    }
                }
            },
            "parameters.K: 'factor' must be > 1, got 0.5",
        ),
        (
            {"parameters": {"J": {"dist": "gamma", "lower": 0.0, "upper": 1.0}}},
            "parameters.J.dist",
        ),
        (
            {"parameters": {"sigma_F": {"dist": "uniform", "lower": -1.0, "upper": 1.0}}},
            "parameters.sigma_F: a standard deviation needs lower >= 0",
        ),
        (
            {"parameters": {"phi": {"dist": "uniform", "lower": 20.0, "upper": 95.0}}},
            "parameters.phi: the prior's range [20, 95] leaves the simulator's range of phi",
        ),
        (
            {"parameters": {"K": {"dist": "log_uniform", "lower": -1.0, "upper": 1e8}}},
            "parameters.K",
        ),
        (
            {"nominal": {"J": 0.002, "sigma_T": 0.5, "sigma_z": 0.001}},
            "parameters.J: 'J' is both calibrated and nominal",
        ),
        ({"nominal": {"sigma_T": 0.5}}, "sigma_z: response z is used but sigma_z"),
        ({"nominal": {"sigma_T": 0.5, "sigma_z": 0.0}}, "nominal.sigma_z: must be a number > 0"),
        (
            {"nominal": {"sigma_T": 0.5, "sigma_z": 0.001, "bogus": 1}},
            "nominal.bogus: unknown name 'bogus'",
        ),
        (
            {"nominal": {"sigma_T": 0.5, "sigma_z": 0.001, "n": 9.0}},
            "nominal.n: Input should be less than or equal to 5",
        ),
        ({"simulator": {"dtt": 0.01}}, "simulator.dtt: unknown rig/numerics key 'dtt'"),
        (
            {"simulator": {"duration": 5.0, "offset_F": 20.0}},
            "simulator: duration 5 s is not longer than",
        ),
        ({"simulator": {"duration": 12.0, "J": 0.1}}, "simulator.J: unknown rig/numerics key"),
        (
            {"simulator": {"duration": 12.0, "drive_digging": "deep"}},
            "drive_digging: Input should be 'thinning' or 'mobilised'",
        ),
        ({"sampler": {"n_samples": 3}}, "sampler.n_samples: Input should be greater than"),
        ({"sampler": {"moves": "gibbs"}}, "sampler.moves"),
        (
            {"sampler": {"resampling": "stratified"}},
            "sampler.resampling: Input should be 'systematic' or 'multinomial'",
        ),
        ({"sampler": {"n_sample": 30}}, "sampler.n_sample: unknown field"),
        ({"likelihood": "laplace"}, "likelihood"),
        ({"responses": ["F", "F"]}, "responses: must be distinct"),
        ({"colour": "red"}, "colour: unknown field"),
        ({"name": None}, "name: required field is missing"),
        ({"parameters": {}}, "parameters: at least one calibrated parameter"),
        ({"reference": {"zeta": 1.0}}, "reference.zeta: unknown parameter"),
    ],
)
def test_validation_errors_name_the_field(changes: dict, needle: str) -> None:
    with pytest.raises(CaseError) as info:
        build(**changes)
    msg = str(info.value)
    assert needle in msg, msg
    assert "\n" not in msg


def test_sampler_resampling_reaches_the_tmcmc_settings() -> None:
    """A systematic case keeps the fingerprint it had before the key existed; multinomial
    reaches the settings and changes it; the stored document names it and reads back equal."""
    base = build(sampler={"moves": "leader"})
    assert base.tmcmc_settings().resampling == "systematic"
    same = build(sampler={"moves": "leader", "resampling": "systematic"})
    assert same.fingerprint() == base.fingerprint()
    multi = build(sampler={"moves": "leader", "resampling": "multinomial"})
    assert multi.tmcmc_settings().resampling == "multinomial"
    assert multi.fingerprint() != base.fingerprint()
    for case in (base, multi):
        assert case.to_dict()["sampler"]["resampling"] == case.sampler.resampling
        assert CaseDefinition.from_dict(case.to_dict()) == case


def test_a_study_takes_its_move_schemes_form_unless_it_names_the_settings() -> None:
    """No [sampler] table: the accelerated accurate form (waste-free chains of surrogate
    transitions of 40 steps with population jumps, log walk, multinomial resampling).
    "resample-move": the unaccelerated accurate form (plain steps, linear walk, systematic
    resampling), as before the form defaults.
    Named settings win; a changed move scheme brings its own defaults for what the case left
    out, and keeps what it named."""
    default = build().tmcmc_settings()
    assert default == TMCMCSettings(moves="waste-free", **form_defaults("waste-free"))
    accurate = build(sampler={"moves": "resample-move"}).tmcmc_settings()
    assert accurate.moves == "resample-move" and accurate.n_steps is None
    assert (accurate.delayed_acceptance, accurate.surrogate_steps) == (False, 1)
    assert accurate.surrogate_jumps == 0.0
    assert (accurate.proposal_scale, accurate.resampling) == ("linear", "systematic")
    assert accurate == TMCMCSettings()  # the library's defaults
    fast = build(sampler={"moves": "waste-free"}).tmcmc_settings()
    assert fast.n_steps == 4 and fast.moves == "waste-free"  # filled in (WASTE_FREE_STEPS)
    assert (fast.delayed_acceptance, fast.surrogate_steps) == (True, 40)
    assert fast.surrogate_jumps == 0.2
    assert (fast.proposal_scale, fast.resampling) == ("log", "multinomial")
    leader = build(sampler={"moves": "leader"})
    paper = leader.tmcmc_settings()
    assert (paper.delayed_acceptance, paper.surrogate_steps) == (False, 1)
    assert paper.surrogate_jumps == 0.0
    assert (paper.proposal_scale, paper.resampling) == ("linear", "systematic")
    switched = leader.with_changes(sampler={"moves": "waste-free"})
    assert switched.tmcmc_settings().delayed_acceptance is True
    assert switched.tmcmc_settings().resampling == "multinomial"
    assert switched.tmcmc_settings().surrogate_jumps == 0.2
    # a share the case named stays, also at 0 (no jumps in the accelerated form)
    still = build(sampler={"moves": "waste-free", "surrogate_jumps": 0.0})
    assert still.tmcmc_settings().surrogate_jumps == 0.0
    named = build(sampler={"moves": "leader", "proposal_scale": "log"})
    assert named.with_changes(sampler={"moves": "waste-free"}).sampler.proposal_scale == "log"
    plain = build(sampler={"moves": "waste-free", "delayed_acceptance": False})
    assert plain.tmcmc_settings().delayed_acceptance is False
    # null is "the form's default", as leaving the key out
    assert build(sampler={"moves": "leader", "resampling": None}) == leader
    # the stored document names the resolved form, so it does not change with the defaults
    assert leader.to_dict()["sampler"]["delayed_acceptance"] is False


def test_toml_errors_are_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\n[parameters\n')
    with pytest.raises(CaseError) as info:
        load_case(bad)
    assert str(info.value).startswith("bad.toml: case file is not valid TOML")
    assert "\n" not in str(info.value)
    with pytest.raises(CaseError, match="cannot read case file"):
        load_case(tmp_path / "missing.toml")
    (tmp_path / "unknown.toml").write_text(TOML.replace("k_phi =", "k_phy ="))
    with pytest.raises(CaseError, match=r"^unknown.toml: parameters.k_phy: unknown parameter"):
        load_case(tmp_path / "unknown.toml")


@pytest.mark.parametrize("key", ["1", "2a", "2b"])
def test_presets_match_table2(key: str) -> None:
    case = preset_case(key)
    table = table2_prior(key)
    assert case.prior().names == table.names
    assert case.prior().dists == table.dists
    assert dict(case.prior().units) == dict(table.units)
    extra = "J" if key == "1" else "R"
    assert case.parameter_names == (
        "k_c",
        "k_phi",
        "n",
        "phi",
        extra,
        "sigma_F",
        "sigma_T",
        "sigma_z",
    )
    fixed = "R" if key == "1" else "J"
    assert case.nominal == {fixed: TABLE2_NOMINAL[fixed]}
    assert case.sampler.n_samples == 2000 and case.sampler.moves == "leader"
    assert case.likelihood == "normalized"
    assert case.data.offset == 40.0
    assert (case.simulator["duration"], case.simulator["offset_z"]) == (50.0, 1.0)


def test_presets_2a_2b_differ_only_by_seed() -> None:
    a, b = preset_case("2a").to_dict(), preset_case("2b").to_dict()
    assert a["seed"] != b["seed"]
    for doc in (a, b):
        for key in ("seed", "name", "description"):
            doc.pop(key)
    assert a == b
    with pytest.raises(CaseError, match="unknown preset"):
        preset_case("3")


@pytest.mark.parametrize(
    ("key", "stem", "files"),
    [
        ("quick", "quick", ("wf34_s020.csv", "wf34_s050.csv")),
        ("1", "case1", ("wf34_s020.csv",)),
        ("2a", "case2a", ("wf34_s020.csv",)),
        ("2b", "case2b", ("wf34_s020.csv",)),
    ],
)
def test_example_case_files_are_the_presets(key: str, stem: str, files: tuple[str, ...]) -> None:
    case = load_case(EXAMPLES / f"{stem}.toml")
    assert case.to_dict() == preset_case(key, files).to_dict()
    assert all(p.is_file() for p in case.data_paths())


def test_preset_costs_follow_the_samplers_plan() -> None:
    """The model runs of a preset's study: n_samples at the prior's stage, then the measured
    share of what the moves plan per stage: the paper's leader form one run per sample
    (2000), the quick case's waste-free chains of P = 5 states n - n/P = 400 (Dau & Chopin
    2022); the measured stages and share are those of a real run (the README walk checks the
    quick case's)."""
    assert next(iter(PRESETS)) == "quick"  # offered first
    assert stage_runs(preset_case("1")) == 2000
    assert stage_runs(preset_case("quick")) == 400
    for key, preset in PRESETS.items():
        cost = preset_cost(key)
        n = preset_case(key).sampler.n_samples
        later = preset.stages * preset.share * stage_runs(preset_case(key))
        assert cost.model_runs == n + round(later)
        assert cost.minutes == pytest.approx(cost.model_runs * preset.run_s / 60)
        assert cost.text().startswith(f"about {cost.model_runs:,} model runs, ")
    assert preset_cost("1", n_samples=500).model_runs == 500 + round(6 * 0.64 * 500)


def test_a_seed_a_study_cannot_store_is_refused_naming_it() -> None:
    """A seed is a signed 64-bit integer (what the service stores): the CLI refuses a case
    file the API would refuse, with the field named."""
    assert CaseDefinition.from_dict({**BASE, "seed": 2**63 - 1}).seed == 2**63 - 1
    for bad in (2**63, -1):
        with pytest.raises(CaseError, match=r"^seed: "):
            CaseDefinition.from_dict({**BASE, "seed": bad})

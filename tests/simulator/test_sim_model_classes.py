"""Named model classes (``RigConfig.model``, scm_core/simulator/models.py; issue 72)."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from scm_core.calibration import load_case
from scm_core.calibration.case import CaseError
from scm_core.calibration.model import build_configs
from scm_core.simulator import RigConfig, simulate_swt
from scm_core.simulator.models import MODEL_CLASSES, MODEL_NAMES

QUICK = load_case(Path(__file__).resolve().parents[2] / "examples" / "quick.toml")
PHYSICS = {k for preset in MODEL_CLASSES.values() for k in preset}


def _physics(rig: RigConfig) -> dict:
    return {k: v for k, v in rig.model_dump().items() if k in PHYSICS}


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_each_class_sets_valid_options_and_no_numerics(name: str) -> None:
    preset = MODEL_CLASSES[name]
    assert set(preset) <= set(RigConfig.model_fields) - {"model"}
    rig = RigConfig(model=name)
    assert _physics(rig) == dict(preset)
    numerics = ("dx", "dt", "duration", "offset_F", "offset_z_fraction", "steady_tolerance")
    assert not set(preset) & {*numerics, "sinkage_datum", "slip_angle", "W"}


def test_scm_is_the_papers_defaults() -> None:
    """The paper's presets are the scm class: its options are the simulator's defaults."""
    assert _physics(RigConfig(model="scm")) == _physics(RigConfig())


def test_the_classes_differ_in_every_option_the_cmu_wheels_needed() -> None:
    scm, flow = MODEL_CLASSES["scm"], MODEL_CLASSES["scm_flow"]
    differ = {k for k in scm if scm[k] != flow[k]}
    assert differ == {
        "shear",
        "drive_digging",
        "skid_ploughing",
        "grouser_contact",
        "grouser_slip",
        "stuck_shear",
        "pocket_carry",
    }


def test_an_option_the_case_sets_wins_over_its_class() -> None:
    rig = RigConfig(model="scm_flow", grouser_slip="rim", shear="velocity")
    assert (rig.grouser_slip, rig.shear, rig.pocket_carry) == ("rim", "velocity", "kept")
    assert rig.replace(W=100.0).grouser_slip == "rim"  # a copy keeps what it was given


def test_an_unknown_class_is_refused_with_the_names() -> None:
    with pytest.raises(ValidationError, match="scm_flow"):
        RigConfig(model="bekker")
    with pytest.raises(CaseError, match=r"simulator\.model.*'scm' or 'scm_flow'"):
        QUICK.with_changes(simulator={**QUICK.simulator, "model": "bekker"})


def test_the_scm_class_runs_the_papers_physics_bit_for_bit() -> None:
    rig = RigConfig(duration=6.0, offset_F=2.0, offset_T=2.0, offset_z=1.0)
    named = rig.model_copy(update={"model": "scm"})
    assert simulate_swt(rig=RigConfig.model_validate(named.model_dump())).means == (
        simulate_swt(rig=rig).means
    )


def test_a_case_names_its_class_and_builds_the_same_rig_as_spelled_out() -> None:
    named = QUICK.with_changes(simulator={**QUICK.simulator, "model": "scm_flow"})
    spelled = QUICK.with_changes(simulator={**QUICK.simulator, **MODEL_CLASSES["scm_flow"]})
    cond = {"W": 20.0, "R": 0.058, "b": 0.05, "slip": 0.5}
    rig_n = build_configs(named.nominal, named.simulator, cond, {"phi": 30.0})[2]
    rig_s = build_configs(spelled.nominal, spelled.simulator, cond, {"phi": 30.0})[2]
    assert _physics(rig_n) == _physics(rig_s)


def test_each_name_expands_to_the_options_docs_simulator_md_documents() -> None:
    """docs/simulator.md's "Model classes" table (option rows, a column per class) is what the
    classes set: each documented value, and no option of a class left out of the table."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "simulator.md").read_text()
    section = text.split("## Model classes", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    header = next(line for line in section.splitlines() if line.startswith("| option"))
    names = [c.strip().strip("`") for c in header.strip("|").split("|")[1:]]
    assert names == list(MODEL_NAMES)
    documented: dict[str, dict[str, object]] = {n: {} for n in names}
    for line in rows:
        cells = [c.strip() for c in line.strip("|").split("|")]
        # "`shear` (eq. 8)" or "`bulldozing`, `border_taper`": the options the row is of
        options = [o.strip("`") for o in cells[0].split("(")[0].replace(",", " ").split()]
        for name, cell in zip(names, cells[1:], strict=True):
            value: object = {"on": True, "off": False}.get(cell, cell.strip("`"))
            for option in options:
                documented[name][option] = value
    for name in names:
        assert documented[name] == dict(MODEL_CLASSES[name]), name

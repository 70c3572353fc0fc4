"""A priors file for ``twin identify --priors``: every prior a finite value and a usable sigma,
every problem of the file one line naming the file and the key, exit 2 (no traceback, no
RuntimeWarning of a fit that divides by a sigma of zero or squares one of 1e-300)."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.cli import main
from twin.errormodel.coefficients import PRIOR_MAX, PRIOR_SIGMA_MIN, load_priors, priors_path
from twin.errors import ConfigErrors

#: the committed file's first prior, as it is written there
HEEL = "[priors.alpha_l_heel_block]\nvalue = 1.1e-6\nsigma = 0.44e-6\n"


def _priors(tmp_path: Path, replacement: str) -> Path:
    """The committed priors with the heel block's value and sigma replaced."""
    text = priors_path().read_text(encoding="utf-8")
    assert HEEL in text  # the committed file as this test knows it
    path = tmp_path / "priors.toml"
    path.write_text(text.replace(HEEL, "[priors.alpha_l_heel_block]\n" + replacement), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("replacement", "key", "word"),
    [
        ("value = 1.1e-6\nsigma = 0\n", "sigma", "> 0"),
        ("value = 1.1e-6\nsigma = -1\n", "sigma", "> 0"),
        ("value = 1.1e-6\nsigma = 1e-300\n", "sigma", "> 0"),
        ("value = 1.1e-6\nsigma = 1e308\n", "sigma", "> 0"),
        ("value = 1.1e-6\nsigma = inf\n", "sigma", "> 0"),
        ("value = 1.1e-6\nsigma = nan\n", "sigma", "> 0"),
        ('value = 1.1e-6\nsigma = "0.4 um"\n', "sigma", "> 0"),
        ("value = 1e308\nsigma = 0.44e-6\n", "value", "finite number within"),
        ("value = -1e7\nsigma = 0.44e-6\n", "value", "finite number within"),
        ("value = nan\nsigma = 0.44e-6\n", "value", "finite number"),
        ("sigma = 0.44e-6\n", "value", "missing"),
    ],
)
def test_a_prior_the_fit_cannot_use_gets_one_line_and_exit_2(
    replacement: str, key: str, word: str, tmp_path: Path, capsys
) -> None:
    path = _priors(tmp_path, replacement)
    assert main(["identify", "--priors", str(path), "--out", str(tmp_path / "out.toml"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "Warning" not in err
    lines = err.strip().splitlines()
    assert lines == [lines[0]] and lines[0].startswith(f"twin: {path}: priors.alpha_l_heel_block.{key}: "), (
        err
    )
    assert word in lines[0], err
    assert not (tmp_path / "out.toml").exists()


def test_every_bad_prior_of_a_file_is_reported_at_once(tmp_path: Path) -> None:
    path = _priors(tmp_path, "value = 1e308\nsigma = 0\n")
    text = path.read_text(encoding="utf-8").replace("sigma = 0.88e-7", "sigma = 1e-300")
    text = text.replace('unit = "rad"', 'unit = "deg"')
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigErrors) as caught:
        load_priors(path)
    assert [(p.source, p.key) for p in caught.value.problems] == [
        (str(path), "priors.alpha_l_heel_block.value"),
        (str(path), "priors.alpha_l_heel_block.sigma"),
        (str(path), "priors.alpha_l_spindle.sigma"),
        (str(path), "priors.runout_phase.unit"),
    ]
    assert len(str(caught.value).splitlines()) == 4


def test_the_bounds_are_far_beyond_the_committed_priors() -> None:
    """The committed priors are well inside the bounds (they are about absurd files, not
    about a tester's knowledge), and the bounds themselves are accepted."""
    for name, prior in load_priors().items():
        assert abs(prior.value) < PRIOR_MAX / 1e3, name
        assert prior.sigma is None or PRIOR_SIGMA_MIN * 1e3 < prior.sigma < PRIOR_MAX / 1e3, name


def test_a_prior_at_the_bounds_is_accepted(tmp_path: Path) -> None:
    path = _priors(tmp_path, f"value = {-PRIOR_MAX}\nsigma = {PRIOR_SIGMA_MIN}\n")
    prior = load_priors(path)["alpha_l_heel_block"]
    assert (prior.value, prior.sigma) == (-PRIOR_MAX, PRIOR_SIGMA_MIN)

"""Calibrate the thermal network to the paper's seven measured temperature rises, with priors.

The network's capacities and conductances come from the drawing (:mod:`twin.config.drawing`, :mod:`twin.calibration.geometry`). Seven rises
cannot identify its 28 uncertain values, so the fit is posed as a regularised (maximum a
posteriori) least squares in log-factors on the drawing's values:

    minimise  sum_b ((rise_b(theta) - measured_b) / sigma_meas)^2  +  sum_k (theta_k / sigma_k)^2

with ``sigma_meas`` the rises' measurement uncertainty and ``sigma_k`` each value's documented
spread (docs/reference/facts.md 6: convection 30 %, bolted joints 50 %, capacities from geometry 5 %; the
transmission's mass and the floor slab are guesses, 50 %). No parameter has a bound, so none can end at one. The data move
only the directions they inform: the report gives the rank of the rises' Jacobian, how many
directions the data inform more than the priors do, each parameter's posterior standard error
and 95 % interval (from the Gauss-Newton covariance at the optimum), and the fit under three room
shapes (the paper gives only the room's rise). The measured probe drift (-0.021 mm) plays no
part: it is validation data.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from twin.config.spec import NS_PER_S, Scenario
from twin.errors import ConfigError
from twin.files import write_text_atomic
from twin.paper import EXPERIMENT_S, TEMPERATURE_RISE_K
from twin.pipeline.prepare import prepare_scenario
from twin.pipeline.stages import simulate
from twin.uncertainty import rooms

#: which thermal-network node sits at each of the paper's measuring points (room: the network's
#: input): the network the calibration fits is a ThermalNetwork
NODE_OUTPUTS: dict[str, str] = {
    "bearing_block": "t_bearing_block_cap",  # on the block's top face, above the spindle's axis
    "heel_block": "t_heel_block",
    "bearing": "t_bearing",
    "t_plate": "t_t_plate",
    "base": "t_base",
    "long_pole": "t_pole_lower",
    "detecting_frame": "t_detecting_frame_lower",  # the paper: "the bottom of the detecting frame"
    "room": "t_ambient",
}


#: the fitted values and their prior relative spread (sigma of the log-factor) with its reason
PRIORS: dict[str, tuple[float, str]] = {
    "g_base_room": (0.3, "convection + radiation, facts 6: 30 %"),
    "g_heel_block_room": (0.3, "convection + radiation, facts 6: 30 %"),
    "g_bearing_block_room": (0.3, "convection + radiation, facts 6: 30 %"),
    "g_spindle_room": (0.3, "convection + radiation, facts 6: 30 %"),
    "g_t_plate_room": (0.3, "convection + radiation, facts 6: 30 %"),
    "g_detecting_frame_room": (0.3, "convection + radiation, facts 6: 30 %"),
    "g_base__heel_block": (0.5, "bolted joint, facts 6: 50 %"),
    "g_heel_block__bearing_block": (0.5, "bolted joint, facts 6: 50 %"),
    "g_bearing_block__spindle": (0.5, "through the roller bearing, facts 6: 50 %"),
    "g_spindle__bearing": (0.5, "ring seat, facts 6: 50 %"),
    "g_bearing__t_plate": (0.5, "PTFE liner and ring seat, facts 6: 50 %"),
    "g_base__detecting_frame": (0.5, "bolted joint, facts 6: 50 %"),
    "c_base": (0.05, "capacity from geometry, facts 6: 5 %"),
    "c_heel_block": (0.05, "capacity from geometry, facts 6: 5 %"),
    "c_bearing_block": (0.05, "capacity from geometry, facts 6: 5 %"),
    "c_spindle": (0.05, "capacity from geometry, facts 6: 5 %"),
    # the transmission behind the spindle and the floor it stands on (tester-geometry.toml)
    "c_drive_train": (0.5, "the transmission's mass is a guess (estimate): 50 %"),
    "g_drive_train_room": (0.3, "convection + radiation, facts 6: 30 %"),
    "g_spindle__drive_train": (0.5, "keyed coupling hub, a joint: facts 6, 50 %"),
    "g_drive_train__floor": (0.5, "the bed bolted on the floor, a joint: facts 6, 50 %"),
    "c_floor": (0.5, "the slab's area and the depth 8 h reach are estimates: 50 %"),
    "g_floor_room": (0.5, "downward free convection, handbook 0.5-1.5 W/(m2 K): 50 %"),
    # the two halves of the bearing block: conduction through the iron between them
    "g_bearing_block__bearing_block_cap": (
        0.3,
        "conduction k A / L through the block, section and path estimated: 30 %",
    ),
    "g_bearing_block__bearing_block_rear": (
        0.3,
        "conduction k A / L through the block, section and path estimated: 30 %",
    ),
    # the embedded station's heat under the base: nothing measured, a factor e either way
    "hyd_share_base": (1.0, "the embedded station's heat share, an estimate: a factor e"),
    "hyd_share_pole_lower": (1.0, "the embedded station's heat share, an estimate: a factor e"),
    "hyd_share_detecting_frame_lower": (1.0, "the embedded station's heat share, an estimate: a factor e"),
    "hyd_share_t_plate": (1.0, "the loading cylinder's heat share, an estimate: a factor e"),
}
#: parameters that move with a fitted one (the frame's two halves share one surface factor)
TIED: dict[str, str] = {
    "g_detecting_frame_lower_room": "g_detecting_frame_room",
    # the bearing block's two halves: one casting, one surface, one foot
    "c_bearing_block_rear": "c_bearing_block",
    "g_bearing_block_rear_room": "g_bearing_block_room",
    "g_heel_block__bearing_block_rear": "g_heel_block__bearing_block",
    "c_bearing_block_cap": "c_bearing_block",
    "g_bearing_block_cap_room": "g_bearing_block_room",
    "g_bearing_block_rear__bearing_block_cap": "g_bearing_block__bearing_block_cap",
}
#: a share that is the rest of the others: the oil keeps what the parts under the base do not take
REST: dict[str, tuple[str, ...]] = {
    "hyd_share_oil": (
        "hyd_share_base",
        "hyd_share_pole_lower",
        "hyd_share_detecting_frame_lower",
        "hyd_share_t_plate",
    )
}
#: uncertainty of a measured rise, K [estimate: one thermometer per point, the paper reads each
#: rise to 0.1 K; a rise cancels the thermometer's offset, and where the lumps hid a gradient at
#: a thermometer (the bearing block's cap, the frame's bottom, the pole's lower part) the network
#: now has a node for it, so what is left of the placement is about a tenth of a kelvin]
SIGMA_MEAS_K = 0.15
BODIES = ("bearing_block", "heel_block", "bearing", "t_plate", "base", "long_pole", "detecting_frame")
#: the room shapes the fit is repeated under (the scenario's own first)
ROOM_SHAPES = rooms.ROOM_SHAPES
ROOM_KEY = "input.thermal.t_room"


@dataclass(frozen=True)
class ThermalFit:
    """One fit: values, their estimates, posterior standard errors (relative), rises, diagnostics."""

    values: dict[str, float]
    estimates: dict[str, float]
    rel_std_error: dict[str, float]
    rises: dict[str, float]
    jacobian_rank: int
    informed_directions: int
    singular_values: list[float]
    cost: float


def thermal_instance(scenario: Scenario) -> str:
    names = [f.name for f in scenario.fmus if f.model == "ThermalNetwork"]
    if len(names) != 1:
        raise ConfigError(
            "calibration needs exactly one ThermalNetwork instance", source=scenario.source_path
        )
    return names[0]


def thermal_only(scenario: Scenario, params: Mapping[str, float]) -> Scenario:
    """The scenario cut down to its thermal network, with ``params`` overriding its parameters."""
    name = thermal_instance(scenario)
    scenario = scenario.with_parameters(name, params, "calibration trial")
    spec = scenario.fmu(name)
    return dataclasses.replace(
        scenario,
        fmus=(spec,),
        connections=(),
        profiles=tuple(p for p in scenario.profiles if p.target.startswith(name + ".")),
        events=tuple(e for e in scenario.events if e.target.startswith(name + ".")),
        step_ns=spec.period_ns,
        output_interval_ns=scenario.duration_ns,
    )


def node_rises(scenario: Scenario, params: Mapping[str, float]) -> dict[str, float]:
    """Rise of each measured node over the run."""
    sub = thermal_only(scenario, params)
    name = sub.fmus[0].name
    columns = {body: f"{name}.{NODE_OUTPUTS[body]}" for body in BODIES}
    simulation = simulate(prepare_scenario(sub), keep=columns.values())
    if simulation.result.error:
        raise simulation.result.error
    table = simulation.table
    return {body: float(table[col][-1] - table[col][0]) for body, col in columns.items()}


def _estimates(scenario: Scenario) -> dict[str, float]:
    spec = scenario.fmu(thermal_instance(scenario))
    names = list(PRIORS) + list(TIED) + list(REST)
    missing = [k for k in names if k not in spec.parameters]
    if missing:
        raise ConfigError(
            f"the thermal network's {', '.join(missing)} must come from the geometry (base/geometry-thermal.toml)",
            source=scenario.source_path,
        )
    return {k: float(spec.parameters[k].value) for k in names}


def calibrate(scenario: Scenario) -> ThermalFit:
    """The regularised fit of :data:`PRIORS` to the paper's rises under the scenario's room."""
    if scenario.duration_ns != EXPERIMENT_S * NS_PER_S:
        raise ConfigError(
            "the calibration replays the 480 min experiment",
            source=scenario.source_path,
            key="scenario.duration",
        )
    est = _estimates(scenario)
    names = list(PRIORS)
    sigma = np.array([PRIORS[k][0] for k in names])
    target = np.array([TEMPERATURE_RISE_K[b] for b in BODIES])

    def params_of(x: np.ndarray) -> dict[str, float]:
        p = {k: est[k] * float(np.exp(xi)) for k, xi in zip(names, x, strict=True)}
        p.update({k: est[k] * p[src] / est[src] for k, src in TIED.items()})
        p.update({k: 1.0 - sum(p[s] for s in shares) for k, shares in REST.items()})
        return p

    def data_part(x: np.ndarray) -> np.ndarray:
        rises = node_rises(scenario, params_of(x))
        return (np.array([rises[b] for b in BODIES]) - target) / SIGMA_MEAS_K

    def residual(x: np.ndarray) -> np.ndarray:
        return np.concatenate([data_part(x), x / sigma])

    sol = least_squares(residual, np.zeros(len(names)), method="lm", diff_step=1e-4, xtol=1e-8, ftol=1e-8)
    jac = sol.jac
    cov = np.linalg.pinv(jac.T @ jac)
    j_data = jac[: len(BODIES)]
    sv_raw = np.linalg.svd(j_data, compute_uv=False)
    # prior-whitened data Jacobian: a singular value above 1 is a direction the rises inform
    # more than the priors do
    sv = np.linalg.svd(j_data * sigma, compute_uv=False)
    values = params_of(sol.x)
    return ThermalFit(
        values=values,
        estimates=est,
        rel_std_error={k: float(np.sqrt(cov[i, i])) for i, k in enumerate(names)},
        rises=node_rises(scenario, values),
        jacobian_rank=int(np.sum(sv_raw > sv_raw[0] * 1e-6)),
        informed_directions=int(np.sum(sv > 1.0)),
        singular_values=[float(s) for s in sv],
        cost=float(2 * sol.cost),
    )


def _with_room_shape(scenario: Scenario, name: str) -> Scenario:
    """The scenario with its room rise in shape ``name`` (same start, rise and rise time)."""
    target = ROOM_KEY.split(".", 1)[1]
    return scenario.with_input(rooms.shaped(scenario, target, name, source=f"twin calibrate: room {name}"))


def write_parameter_file(path: Path, cal: ThermalFit, by_shape: Mapping[str, ThermalFit]) -> None:
    """The calibrated values with their source and standard error, as a scenario parameter file."""
    lines = [
        "# Thermal network: the drawing's values (base/geometry-thermal.toml) updated by the paper's seven",
        "# measured rises in a regularised least squares with documented priors (src/twin/calibration/thermal.py).",
        "# Made by `twin calibrate --write`; the probe drift is NOT used here.",
        f"# Rises at 480 min (K, twin vs paper, measurement sigma {SIGMA_MEAS_K} K): "
        + ", ".join(f"{b} {cal.rises[b]:.2f}/{TEMPERATURE_RISE_K[b]}" for b in BODIES),
        f"# Rank of the rises' Jacobian: {cal.jacobian_rank} of {len(PRIORS)} parameters; directions the rises "
        f"inform more than the priors: {cal.informed_directions}; weighted cost {cal.cost:.2f}.",
        "# Room shape (the paper gives only the rise): fitted value under exponential / ramp / s-curve rooms:",
    ]
    for k in PRIORS:
        lines.append(f"#   {k}: " + " / ".join(f"{by_shape[s].values[k]:.4g}" for s in by_shape))
    lines += ["", "[parameters]"]
    for k in sorted(cal.values):
        if k in REST:
            # the rest of the six-digit values written above, in full: the shares must sum to 1
            rest = 1.0 - sum(float(f"{cal.values[o]:.6g}") for o in REST[k])
            lines.append(
                f'{k} = {{ value = {rest!r}, source = "calibrated: the rest of the '
                f"station's heat, 1 - {' - '.join(REST[k])} (drawing {cal.estimates[k]:.4g})\" }}"
            )
            continue
        src = TIED.get(k, k)
        sigma, why = PRIORS[src]
        se = cal.rel_std_error[src]
        value = cal.values[k]
        lo, hi = value * np.exp(-1.96 * se), value * np.exp(1.96 * se)
        note = (
            f"calibrated: drawing {cal.estimates[k]:.4g}, prior sigma {sigma:.0%} ({why}), posterior "
            f"{se:.0%}, 95 % [{lo:.4g}, {hi:.4g}]" + (f"; tied to {src}" if k in TIED else "")
        )
        lines.append(
            f'{k} = {{ value = {float(f"{value:.6g}")!r}, std_error = {float(f"{value * se:.3g}")!r}, source = "{note}" }}'
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, "\n".join(lines) + "\n")  # never through a planted link


def report(cal: ThermalFit, by_shape: Mapping[str, ThermalFit]) -> dict[str, Any]:
    """The fit as JSON-able data (written beside the parameter file)."""
    return {
        "rises_K": {b: {"twin": cal.rises[b], "paper": TEMPERATURE_RISE_K[b]} for b in BODIES},
        "sigma_meas_K": SIGMA_MEAS_K,
        "jacobian_rank": cal.jacobian_rank,
        "informed_directions": cal.informed_directions,
        "singular_values_prior_whitened": cal.singular_values,
        "parameters": {
            k: {
                "value": cal.values[k],
                "drawing": cal.estimates[k],
                "prior_rel_sigma": PRIORS[k][0],
                "posterior_rel_sigma": cal.rel_std_error[k],
                "by_room_shape": {s: c.values[k] for s, c in by_shape.items()},
            }
            for k in PRIORS
        },
        "rises_by_room_shape_K": {s: c.rises for s, c in by_shape.items()},
    }


def calibrate_file(scenario_path: Path | None = None, out: Path | None = None, write: bool = False) -> Path:
    """Calibrate the scenario's thermal network under every room shape and write the result.

    The scenario's own calibration file is left out, so the fit starts from the drawing. The
    result goes to ``out``; without it to ``runs/calibrate/`` unless ``write`` asks for the file
    the scenario includes (the repository's calibration is replaced only on request, and never
    a plain install's own copy of it: refused before the fits).
    """
    from twin.config.load import (
        check_not_installed_copy,
        default_scenario_path,
        load_scenario_data,
        read_scenario_data,
    )

    path = scenario_path or default_scenario_path()
    data = read_scenario_data(path)
    fmus = data.get("fmu", {})
    thermal = [n for n, f in fmus.items() if isinstance(f, dict) and f.get("model") == "ThermalNetwork"]
    if len(thermal) != 1:
        raise ConfigError(
            "calibration needs exactly one ThermalNetwork instance", source=str(path), key="fmu"
        )
    files = fmus[thermal[0]].get("parameter_files", [])
    own = [f for f in files if "calibration/" in str(f)]
    fmus[thermal[0]]["parameter_files"] = [f for f in files if f not in own]
    committed = (
        path.parent / own[0] if own else path.parent / "calibration" / f"{path.stem}-thermal-network.toml"
    )
    target = out or (committed if write else Path("runs") / "calibrate" / committed.name)
    if out is None and write:  # before the fits: seconds, and a plain install's copy is refused
        check_not_installed_copy(committed, "--write")
    scenario = load_scenario_data(data, str(path), path.resolve().parent)
    cal = calibrate(scenario)
    # the scenario's own room is the first shape; the others keep its start, rise and rise time
    by_shape = {ROOM_SHAPES[0]: cal} | {
        name: calibrate(_with_room_shape(scenario, name)) for name in ROOM_SHAPES[1:]
    }
    write_parameter_file(target, cal, by_shape)
    write_text_atomic(target.with_suffix(".json"), json.dumps(report(cal, by_shape), indent=2) + "\n")
    return target

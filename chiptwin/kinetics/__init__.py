"""Kinetics: light emitted per assay site. Unit: photons/s (into 4π), integrated to photons.

Level ``closed_form`` (this package): the equations 2–19 of Salama et al., Biosens. Bioelectron.
19 (2004) as pure array functions (:mod:`~chiptwin.kinetics.closed_form`), turned into light
sources (:mod:`~chiptwin.kinetics.sources`) of one common shape, the :class:`PulseTrain`
(:mod:`~chiptwin.kinetics.pulse_train`): per-site sums of exponential pulses with an exact window
integral. Pyrosequencing's dispensation program, key normalisation and base calling live in
:mod:`~chiptwin.kinetics.pyro`.

Level ``cascade`` (Agah et al. 2004): the multi-enzyme pyrosequencing cascade as a stiff ODE
(:mod:`~chiptwin.kinetics.cascade`, constants in :mod:`~chiptwin.kinetics.cascade_params`,
phasing in :mod:`~chiptwin.kinetics.phasing`, calibration in :mod:`~chiptwin.kinetics.calibrate`)
and the reversible mass-action reaction of eqs. 2–4 (:mod:`~chiptwin.kinetics.reversible`). These
names are exported lazily (PEP 562): ``import chiptwin.kinetics`` does not load scipy's ODE
solvers until one of them is used.

Contract (docs/architecture.md): a light source has ``rate(t_s) -> (n_sites, n_t)`` in photons/s
and ``photons(t_edges_s) -> (n_sites, n_windows)``, the exact integral over each window.
"""

from __future__ import annotations

from chiptwin.kinetics.closed_form import (
    ALPHA_ANDO,
    ALPHA_SELIGER_MCELROY,
    ATP_TURNOVER_FLASH_PER_S,
    ATP_TURNOVER_GLOW_PER_S,
    PYRO_APYRASE_PER_S,
    PYRO_TURNOVER_PER_S,
    RONAGHI_PHOTONS_PER_INCORPORATION,
    atp_assay_photons,
    atp_assay_rate,
    catalyst_detection_photons,
    catalyst_detection_rate,
    emission_prefactor,
    incorporation_yield,
    luciferase_label_photons,
    luciferase_label_rate,
    mass_action_rate,
    photon_rate,
    pyrosequencing_amplitude,
    pyrosequencing_photons,
    pyrosequencing_rate,
    substrate_detection_photons,
    substrate_detection_rate,
)
from chiptwin.kinetics.light_source import LightSource, Replicated
from chiptwin.kinetics.pulse_train import PulseTrain, superpose
from chiptwin.kinetics.pyro import (
    FLOW_ORDER_454,
    KEY_454,
    call_sequence,
    flow_incorporations,
    flows_to_sequence,
    key_flow_counts,
    normalise_flows,
)
from chiptwin.kinetics.sources import (
    atp_assay,
    catalyst_detection,
    luciferase_label,
    pyrosequencing,
    substrate_detection,
)

_LAZY: dict[str, str] = {
    "CascadeParams": "chiptwin.kinetics.cascade_params",
    "CascadeSource": "chiptwin.kinetics.cascade",
    "cascade_pyrosequencing": "chiptwin.kinetics.cascade",
    "CalibrationResult": "chiptwin.kinetics.calibrate",
    "fit_light_curve": "chiptwin.kinetics.calibrate",
    "fit_photon_yield": "chiptwin.kinetics.calibrate",
    "photon_yield": "chiptwin.kinetics.calibrate",
    "single_flow_rate": "chiptwin.kinetics.calibrate",
    "FlowModel": "chiptwin.kinetics.chemistry",
    "flow_light": "chiptwin.kinetics.chemistry",
    "flow_value_distribution": "chiptwin.kinetics.chemistry",
    "PRESETS": "chiptwin.kinetics.chemistry_presets",
    "fit_flow_model": "chiptwin.kinetics.chemistry_fit",
    "phased_flows": "chiptwin.kinetics.phasing",
    "phased_signal": "chiptwin.kinetics.phasing",
    "reversible_photons": "chiptwin.kinetics.reversible",
    "reversible_product_M": "chiptwin.kinetics.reversible",
    "reversible_rate": "chiptwin.kinetics.reversible",
    "reversible_source": "chiptwin.kinetics.reversible",
    "solve_reversible": "chiptwin.kinetics.reversible",
}
"""Exports of the cascade level, imported on first use (they pull in scipy's ODE solvers)."""


def __getattr__(name: str):
    """Import a lazily exported name (:data:`_LAZY`) on first access (PEP 562)."""
    if name in _LAZY:
        from importlib import import_module

        value = getattr(import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "ALPHA_ANDO",
    "ALPHA_SELIGER_MCELROY",
    "ATP_TURNOVER_FLASH_PER_S",
    "ATP_TURNOVER_GLOW_PER_S",
    "FLOW_ORDER_454",
    "KEY_454",
    "PYRO_APYRASE_PER_S",
    "PYRO_TURNOVER_PER_S",
    "RONAGHI_PHOTONS_PER_INCORPORATION",
    "LightSource",
    "Replicated",
    "PulseTrain",
    "atp_assay",
    "atp_assay_photons",
    "atp_assay_rate",
    "call_sequence",
    "catalyst_detection",
    "catalyst_detection_photons",
    "catalyst_detection_rate",
    "emission_prefactor",
    "flow_incorporations",
    "flows_to_sequence",
    "incorporation_yield",
    "key_flow_counts",
    "luciferase_label",
    "luciferase_label_photons",
    "luciferase_label_rate",
    "mass_action_rate",
    "normalise_flows",
    "photon_rate",
    "pyrosequencing",
    "pyrosequencing_amplitude",
    "pyrosequencing_photons",
    "pyrosequencing_rate",
    "substrate_detection",
    "substrate_detection_photons",
    "substrate_detection_rate",
    "superpose",
    *_LAZY,
]

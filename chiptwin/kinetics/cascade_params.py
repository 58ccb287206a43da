"""Constants of the pyrosequencing enzyme cascade: one frozen dataclass, units in the field names.

The cascade (Ronaghi, Genome Res. 11, 2001; Agah et al., Nucleic Acids Res. 32:e166, 2004, "a
multi-enzyme model for pyrosequencing": Michaelis–Menten kinetics for all four enzymes)::

    polymerase   DNA_n + dNTP        → DNA_n+1 + PPi
    sulfurylase  PPi + APS           → ATP + SO4
    luciferase   ATP + luciferin     → AMP + PPi + oxyluciferin + hν   (α photons per turnover)
    apyrase      ATP, dNTP           → NDP → NMP + Pi

Every constant below carries its source. ``[lit]`` marks a published value, with the paper
named beside it (tabulated in docs/background/sources.md, Kinetics; the K_d(DNA) of Kuchta et al.
is named but not verified here); ``[choice]`` a documented choice of this twin. Enzyme
*amounts* are assay recipe choices: the defaults are
set so that, in the linear regime (every substrate far below its K_m), the cascade reduces to the
paper's pyrosequencing model, eqs. 18–19, with k_t = 1 s⁻¹ and k_a = 0.05 s⁻¹
(:meth:`CascadeParams.from_closed_form` does the same for any k_t, k_a, α).

Rates used below (linear regime, :meth:`CascadeParams.linear_rates`)::

    k_t = k_cat,L [L] / K_m,L(ATP) · LH0 / (K_m,L(LH) + LH0)      luciferase turnover of ATP
    k_a = k_cat,A(ATP) [A] / K_m,A(ATP)                         apyrase on ATP
    k_d = k_cat,A(dNTP) [A] / K_m,A(dNTP)                       apyrase on a dNTP
    k_s = k_cat,S [S] / K_m,S(PPi) · APS0 / (K_m,S(APS) + APS0)   sulfurylase on PPi
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

from chiptwin.kinetics.closed_form import (
    ALPHA_SELIGER_MCELROY,
    PYRO_APYRASE_PER_S,
    PYRO_TURNOVER_PER_S,
)

# --- literature constants (docs/background/sources.md, Kinetics K17–K22) ------------------------

LUCIFERASE_KM_ATP_FLASH_M: float = 110e-6
"""Luciferase K_m(ATP), flash site (DeLuca & McElroy 1984) [lit]. Unit: M."""

LUCIFERASE_KM_ATP_GLOW_M: float = 20e-6
"""Luciferase K_m(ATP), glow site (DeLuca & McElroy 1984) [lit]. Unit: M."""

LUCIFERASE_KM_LUCIFERIN_M: float = 15e-6
"""Luciferase K_m(luciferin) [lit; listed with the K_i values of Ribeiro & Esteves da Silva 2008,
the primary source not traced here: sources.md K18]. Unit: M."""

LUCIFERASE_KI_LAMP_M: float = 3.8e-9
"""Inhibition constant of dehydroluciferyl-AMP (L-AMP) (Ribeiro & Esteves da Silva 2008)
[lit]. Unit: M."""

LUCIFERASE_KI_OXYLUCIFERIN_M: float = 0.5e-6
"""Inhibition constant of oxyluciferin (Ribeiro & Esteves da Silva 2008) [lit]. Unit: M."""

SULFURYLASE_KM_APS_M: float = 39e-6
"""ATP sulfurylase K_m(APS), ATP-forming direction (rat; Biochem J 301, 1994) [lit]. Unit: M."""

SULFURYLASE_KM_PPI_M: float = 18e-6
"""ATP sulfurylase K_m(PPi), ATP-forming direction (rat; Biochem J 301, 1994) [lit]. Unit: M."""

SULFURYLASE_KCAT_PER_S: float = 6.7
"""ATP sulfurylase turnover, lower bound (Penicillium) [lit]. Unit: 1/s."""

POLYMERASE_KPOL_PER_S: float = 63.0
"""Klenow k_pol for the correct base, low end of 63–250 s⁻¹ (Biochemistry 45:890, 2006)
[lit]. Unit: 1/s."""

POLYMERASE_KD_DNTP_M: float = 12e-6
"""Klenow K_d(dNTP), high end of 3–12 µM (Biochemistry 45:890, 2006) [lit]. Unit: M. With
k_pol at the low end this is the slowest extension the published ranges allow."""

POLYMERASE_KD_DNA_M: float = 5e-9
"""Klenow–primer/template dissociation constant, ≈ 5 nM (Kuchta et al., Biochemistry 26:8410,
1987) [lit, not verified here]. Unit: M."""

# --- choices ------------------------------------------------------------------------------------

SULFURYLASE_FAST_PER_S: float = 100.0
"""Default first-order PPi → ATP rate k_s [choice]: 100 × the paper's k_t, so PPi spends ≈ 1 % of
its time unconverted (the paper's limit takes it as instantaneous). Unit: 1/s."""

APYRASE_DNTP_OVER_ATP: float = 10.0
"""Default ratio k_d / k_a of apyrase's first-order dNTP and ATP clearance [choice]. The paper
gives only k_a (ATP); with k_d = 10 k_a = 0.5 s⁻¹ a flow's nucleotide is cleared to e⁻³⁰ within
a 60 s flow, so residual nucleotide does not carry forward (apyrase clears the well between
flows)."""

_KM_APYRASE_M = 100e-6  # [choice] apyrase K_m for ATP and for dNTP (no published value used)
_KCAT_APYRASE_ATP = 5.0  # [choice] with 1 µM apyrase: k_a = 5 · 1e-6 / 1e-4 = 0.05 s⁻¹
_APYRASE_M = 1e-6  # [choice]
_LUCIFERIN_M = 1e-3  # [choice] 1 mM: far above K_m(LH) = 15 µM
_APS_M = 1e-3  # [choice] 1 mM: far above K_m(APS) = 39 µM
_LUCIFERASE_KCAT = 1.0  # [choice] only k_cat·[L] enters the linear regime


def _saturation(c: float, km: float) -> float:
    """``c / (K_m + c)``, the occupancy of an enzyme by a substrate in excess."""
    return c / (km + c) if c > 0 else 0.0


def _luciferase_for(turnover_per_s: float, kcat: float, km_atp: float, km_lh: float,
                    lh: float) -> float:
    """Luciferase concentration (M) that gives the first-order ATP turnover k_t."""
    sat = _saturation(lh, km_lh)
    return turnover_per_s * km_atp / (kcat * sat) if turnover_per_s > 0 else 0.0


def _sulfurylase_for(rate_per_s: float, kcat: float, km_ppi: float, km_aps: float,
                     aps: float) -> float:
    """ATP sulfurylase concentration (M) that gives the first-order PPi → ATP rate k_s."""
    sat = _saturation(aps, km_aps)
    return rate_per_s * km_ppi / (kcat * sat) if rate_per_s > 0 else 0.0


_DEFAULT_LUCIFERASE_M = _luciferase_for(PYRO_TURNOVER_PER_S, _LUCIFERASE_KCAT,
                                        LUCIFERASE_KM_ATP_FLASH_M, LUCIFERASE_KM_LUCIFERIN_M,
                                        _LUCIFERIN_M)
_DEFAULT_SULFURYLASE_M = _sulfurylase_for(SULFURYLASE_FAST_PER_S, SULFURYLASE_KCAT_PER_S,
                                          SULFURYLASE_KM_PPI_M, SULFURYLASE_KM_APS_M, _APS_M)

# (field, lower bound, strict, upper bound or None)
_BOUNDS: dict[str, tuple[float, bool, float | None]] = {
    "volume_L": (0.0, True, None),
    "alpha": (0.0, False, 1.0),
    "lamp_fraction": (0.0, False, 1.0),
    "incomplete_extension": (0.0, False, 1.0),
    "carry_forward": (0.0, False, 1.0),
}
_POSITIVE = ("_km_", "_kd_", "_ki_")


@dataclass(frozen=True)
class CascadeParams:
    """Constants of one site's pyrosequencing cascade (Agah et al. 2004).

    Concentrations in M, rate constants in 1/s, volume in L. Validated on construction: every
    field finite; concentrations and turnover numbers >= 0; K_m, K_d, K_i and the volume > 0;
    ``alpha`` and the fractions in [0, 1]. Derive variants with :func:`dataclasses.replace`.

    Parameters
    ----------
    volume_L : float
        Reaction volume of the site [choice: 1 nL, a 100 µm cube over a 100 µm diode]. Turns
        amounts (mol) into concentrations and turnovers into photons (paper eq. 3).
    alpha : float
        Photons per light-path luciferase turnover (0.88, Seliger & McElroy, as the paper) [lit].
    polymerase_M, polymerase_kpol_per_s, polymerase_kd_dntp_M, polymerase_kd_dna_M : float
        Klenow concentration [choice: 2 µM, in excess over a 1 µM template], k_pol and K_d(dNTP)
        [lit: Biochemistry 45:890, 2006], K_d(DNA) [lit]. The rate per primed strand is
        ``k_pol θ [dNTP] / (K_d + [dNTP])``, θ the polymerase-bound share of the strands at
        binding equilibrium.
    dntp_M : float
        Nucleotide added by each dispensation [choice: 10 µM, near K_d(dNTP)].
    sulfurylase_M, sulfurylase_kcat_per_s, sulfurylase_km_ppi_M, sulfurylase_km_aps_M : float
        ATP sulfurylase amount [choice: k_s = 100 s⁻¹], turnover and K_m values [lit: Biochem J 301,
        1994].
    aps_M : float
        APS at the start [choice: 1 mM]. Consumed once per ATP made.
    luciferase_M, luciferase_kcat_per_s, luciferase_km_atp_M, luciferase_km_luciferin_M : float
        Luciferase amount [choice: gives the paper's k_t = 1 s⁻¹], k_cat [choice: 1 s⁻¹],
        K_m(ATP) of the flash site (110 µM, matching the paper's flash-type k_t for
        pyrosequencing) and K_m(luciferin) [lit].
    luciferin_M : float
        Luciferin at the start [choice: 1 mM]. Consumed once per luciferase turnover.
    lamp_fraction : float
        Share of luciferase turnovers that form dehydroluciferyl-AMP (L-AMP) instead of light
        [choice: 0, the paper's α per turnover].
    product_inhibition : bool
        If True, oxyluciferin and L-AMP inhibit luciferase competitively with luciferin
        (K_i below) [lit]; off by default, as in the paper.
    ki_oxyluciferin_M, ki_lamp_M : float
        Inhibition constants [lit: Ribeiro & Esteves da Silva 2008].
    apyrase_M, apyrase_kcat_atp_per_s, apyrase_km_atp_M, apyrase_kcat_dntp_per_s,
    apyrase_km_dntp_M : float
        Apyrase amount and its Michaelis–Menten constants for ATP and for each dNTP (competing
        substrates) [choice: k_a = 0.05 s⁻¹ as the paper, k_d = 10 k_a].
    incomplete_extension : float
        Share ε of the strands that do not extend in a flow (phasing; Eltoukhy & El Gamal,
        ICASSP 2006; 454: ≈ 0.1–0.3 %) [choice: 0].
    carry_forward : float
        Share λ of the extending strands that also extend with the previous flow's nucleotide
        (phasing; 454: ≈ 1–2 %) [choice: 0].
    """

    volume_L: float = 1e-9
    alpha: float = ALPHA_SELIGER_MCELROY
    polymerase_M: float = 2e-6
    polymerase_kpol_per_s: float = POLYMERASE_KPOL_PER_S
    polymerase_kd_dntp_M: float = POLYMERASE_KD_DNTP_M
    polymerase_kd_dna_M: float = POLYMERASE_KD_DNA_M
    dntp_M: float = 10e-6
    sulfurylase_M: float = _DEFAULT_SULFURYLASE_M
    sulfurylase_kcat_per_s: float = SULFURYLASE_KCAT_PER_S
    sulfurylase_km_ppi_M: float = SULFURYLASE_KM_PPI_M
    sulfurylase_km_aps_M: float = SULFURYLASE_KM_APS_M
    aps_M: float = _APS_M
    luciferase_M: float = _DEFAULT_LUCIFERASE_M
    luciferase_kcat_per_s: float = _LUCIFERASE_KCAT
    luciferase_km_atp_M: float = LUCIFERASE_KM_ATP_FLASH_M
    luciferase_km_luciferin_M: float = LUCIFERASE_KM_LUCIFERIN_M
    luciferin_M: float = _LUCIFERIN_M
    lamp_fraction: float = 0.0
    product_inhibition: bool = False
    ki_oxyluciferin_M: float = LUCIFERASE_KI_OXYLUCIFERIN_M
    ki_lamp_M: float = LUCIFERASE_KI_LAMP_M
    apyrase_M: float = _APYRASE_M
    apyrase_kcat_atp_per_s: float = _KCAT_APYRASE_ATP
    apyrase_km_atp_M: float = _KM_APYRASE_M
    apyrase_kcat_dntp_per_s: float = APYRASE_DNTP_OVER_ATP * _KCAT_APYRASE_ATP
    apyrase_km_dntp_M: float = _KM_APYRASE_M
    incomplete_extension: float = 0.0
    carry_forward: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.product_inhibition, bool):
            raise ValueError(f"product_inhibition = {self.product_inhibition!r} must be a bool")
        for f in fields(self):
            if f.name != "product_inhibition":
                object.__setattr__(self, f.name, _checked(f.name, getattr(self, f.name)))

    # --- derived quantities ------------------------------------------------------------------

    def linear_rates(self) -> dict[str, float]:
        """First-order rate constants of the linear regime (all substrates ≪ K_m).

        Returns
        -------
        dict
            ``turnover_per_s`` (k_t), ``apyrase_atp_per_s`` (k_a), ``apyrase_dntp_per_s``
            (k_d), ``sulfurylase_per_s`` (k_s), ``polymerase_per_s`` (per strand, at the
            dispensed ``dntp_M``, θ for a vanishing template). Unit: 1/s.
        """
        theta = self.polymerase_M / (self.polymerase_M + self.polymerase_kd_dna_M)
        return {
            "turnover_per_s": self.luciferase_kcat_per_s * self.luciferase_M
            / self.luciferase_km_atp_M
            * _saturation(self.luciferin_M, self.luciferase_km_luciferin_M),
            "apyrase_atp_per_s": self.apyrase_kcat_atp_per_s * self.apyrase_M
            / self.apyrase_km_atp_M,
            "apyrase_dntp_per_s": self.apyrase_kcat_dntp_per_s * self.apyrase_M
            / self.apyrase_km_dntp_M,
            "sulfurylase_per_s": self.sulfurylase_kcat_per_s * self.sulfurylase_M
            / self.sulfurylase_km_ppi_M * _saturation(self.aps_M, self.sulfurylase_km_aps_M),
            "polymerase_per_s": self.polymerase_kpol_per_s * theta
            * _saturation(self.dntp_M, self.polymerase_kd_dntp_M),
        }

    def linear_photons_per_incorporation(self) -> float:
        """Photons per incorporated base in the linear regime: ``α (1 − f_LAMP) k_t / k_a``.

        Notes
        -----
        Each PPi is turned into ATP (sulfurylase); each ATP is either turned over by luciferase
        (probability k_t / (k_t + k_a)), which gives light and the PPi back, or removed by
        apyrase. The number of turnovers per PPi is therefore k_t / k_a — paper eq. 19 integrated
        (17.6 with the paper's values, α·k_t/k_a = 0.88·1/0.05; sources.md K8). Infinite
        when k_a = 0.
        """
        r = self.linear_rates()
        light = self.alpha * (1.0 - self.lamp_fraction) * r["turnover_per_s"]
        if light == 0.0:
            return 0.0
        return light / r["apyrase_atp_per_s"] if r["apyrase_atp_per_s"] > 0 else math.inf

    @classmethod
    def from_closed_form(
        cls,
        turnover_per_s: float = PYRO_TURNOVER_PER_S,
        apyrase_per_s: float = PYRO_APYRASE_PER_S,
        alpha: float = ALPHA_SELIGER_MCELROY,
        *,
        sulfurylase_per_s: float = SULFURYLASE_FAST_PER_S,
        dntp_clearance_per_s: float | None = None,
        **changes: Any,
    ) -> CascadeParams:
        """Cascade constants whose linear regime is the paper's eqs. 18–19 with these k_t, k_a, α.

        Parameters
        ----------
        turnover_per_s : float
            k_t, >= 0 (the scenario's ``k_t_per_s``). Unit: 1/s.
        apyrase_per_s : float
            k_a, >= 0 (the scenario's ``k_a_per_s``). Unit: 1/s.
        alpha : float
            Quantum yield in [0, 1].
        sulfurylase_per_s : float
            First-order PPi → ATP rate k_s, >= 0. Unit: 1/s.
        dntp_clearance_per_s : float or None
            Apyrase's first-order dNTP rate k_d; None gives ``APYRASE_DNTP_OVER_ATP · k_a``.
        **changes
            Any other field, applied first (so the Michaelis constants and substrate levels
            used to size the enzymes are the changed ones).

        Returns
        -------
        CascadeParams
            ``luciferase_M``, ``apyrase_M``, ``apyrase_kcat_dntp_per_s`` and ``sulfurylase_M``
            chosen so that :meth:`linear_rates` gives exactly k_t, k_a, k_d and k_s.
        """
        base = replace(cls(), alpha=alpha, **changes)
        k_t = _checked("turnover_per_s", turnover_per_s)
        k_a = _checked("apyrase_per_s", apyrase_per_s)
        k_s = _checked("sulfurylase_per_s", sulfurylase_per_s)
        k_d = APYRASE_DNTP_OVER_ATP * k_a if dntp_clearance_per_s is None else _checked(
            "dntp_clearance_per_s", dntp_clearance_per_s)
        for name, rate, turnover in (("apyrase_kcat_atp_per_s", k_a, base.apyrase_kcat_atp_per_s),
                                     ("luciferase_kcat_per_s", k_t, base.luciferase_kcat_per_s),
                                     ("sulfurylase_kcat_per_s", k_s,
                                      base.sulfurylase_kcat_per_s),
                                     ("luciferin_M", k_t, base.luciferin_M),
                                     ("aps_M", k_s, base.aps_M)):
            if rate > 0 and turnover == 0:
                raise ValueError(f"{name} = 0.0 cannot give a first-order rate of {rate!r} 1/s: "
                                 "must be > 0")
        apyrase_M = k_a * base.apyrase_km_atp_M / base.apyrase_kcat_atp_per_s if k_a > 0 else 0.0
        kcat_dntp = k_d * base.apyrase_km_dntp_M / apyrase_M if apyrase_M > 0 else 0.0
        return replace(
            base,
            luciferase_M=_luciferase_for(k_t, base.luciferase_kcat_per_s,
                                         base.luciferase_km_atp_M,
                                         base.luciferase_km_luciferin_M, base.luciferin_M),
            apyrase_M=apyrase_M,
            apyrase_kcat_dntp_per_s=kcat_dntp,
            sulfurylase_M=_sulfurylase_for(k_s, base.sulfurylase_kcat_per_s,
                                           base.sulfurylase_km_ppi_M,
                                           base.sulfurylase_km_aps_M, base.aps_M),
        )


def _checked(name: str, value: Any) -> float:
    """A finite float within the field's range; ValueError naming field, value and range."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        try:
            value = float(value)  # numpy scalars
        except (TypeError, ValueError):
            raise ValueError(f"{name} = {value!r} must be a real number") from None
    x = float(value)
    lo, strict, hi = _BOUNDS.get(name, (0.0, any(s in name for s in _POSITIVE), None))
    if not math.isfinite(x):
        raise ValueError(f"{name} = {x!r} is out of range: must be finite")
    if (x <= lo) if strict else (x < lo):
        raise ValueError(f"{name} = {x!r} is out of range: must be {'>' if strict else '>='} "
                         f"{lo:g}" + (f" and <= {hi:g}" if hi is not None else ""))
    if hi is not None and x > hi:
        raise ValueError(f"{name} = {x!r} is out of range: must be in [{lo:g}, {hi:g}]")
    return x

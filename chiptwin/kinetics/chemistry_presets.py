"""Named chemistries: the flow-value model (:class:`chiptwin.kinetics.chemistry.FlowModel`)
fitted to real runs, for ``[assay] chemistry``.

Each preset was fitted by ``chiptwin reads profile`` (:mod:`chiptwin.kinetics.chemistry_fit`:
maximum likelihood of the measured flow-value distributions of true lengths 0–5 on 0.01 bins,
Powell's method within the parameters' ranges, with the chain's noise set to 0: the vendor's
values already carry their instrument's readout noise, which the additive term takes up), on
2026-11-29. The numbers are
rounded to three significant digits; the command refits them and prints the distances.

* ``454_flx``: the GS FLX flow-value profile ``FLX_error_profile.dat`` (PyroNoise, Quince et al.,
  Nature Methods 6:639, 2009; as shipped with the qiime denoiser, Reeder & Knight, Nature
  Methods 7:668, 2010): lengths 0–4 counted from real runs, 5 a fitted normal. 454 sequencing:
  Margulies et al., Nature 437:376, 2005.
* ``454_titanium``: the GS FLX Titanium profile ``Titanium_error_profile.dat``, same sources.
* ``ion_pgm``: Ion Torrent PGM (318 chip, 2012), the 449 reads of ``b7_295_chunk.bam`` (BioD's
  test data), their ``FZ`` flow values against the E. coli K-12 reference under each read
  (CIGAR and ``MD``), 254,710 flows; Rothberg et al., Nature 475:348, 2011. Lengths 4 and 5
  have 1,169 and 738 flows only.

All three fit the empty-flow light best as a lognormal (Balzer et al., Bioinformatics 26:i420,
2010, fitted LogNormal(−2.5, 0.2) to Titanium's 0-mers); Ion's with a mean near 0 and the widest
spread allowed, most of its 0-mers clipped to 0 by the additive term's negative side (60 % of
its stored 0-mers are exactly 0).
"""

from __future__ import annotations

from types import MappingProxyType

from chiptwin.kinetics.chemistry import FlowModel

PRESETS: MappingProxyType[str, FlowModel] = MappingProxyType({
    # FLX_error_profile.dat, lengths 0–5
    "454_flx": FlowModel(flow_yield_cv=0.0595, flow_noise_sd=0.0592, flow_background=0.0148,
                         well_noise_cv=0.999, homopolymer_yield_loss=0.0,
                         empty_flow_law="lognormal", empty_flow_mean=0.0696,
                         empty_flow_sd=0.0149),
    # Titanium_error_profile.dat, lengths 0–5
    "454_titanium": FlowModel(flow_yield_cv=0.0774, flow_noise_sd=0.0483,
                              flow_background=0.0177, well_noise_cv=0.873,
                              homopolymer_yield_loss=0.00191, empty_flow_law="lognormal",
                              empty_flow_mean=0.103, empty_flow_sd=0.0513),
    # b7_295_chunk.bam against its alignment's reference, lengths 0–5; the empty-flow sd sits
    # at its range's end (0.5): a light near 0 in most flows and bright in a few
    "ion_pgm": FlowModel(flow_yield_cv=0.0787, flow_noise_sd=0.132, flow_background=-0.0178,
                         well_noise_cv=1.05, homopolymer_yield_loss=0.00416,
                         empty_flow_law="lognormal", empty_flow_mean=0.0103,
                         empty_flow_sd=0.5),
})
"""The fitted chemistries by name (module docstring)."""

PRESET_NAMES: tuple[str, ...] = tuple(PRESETS)

#: The ``[assay]`` keys a preset sets: the model's fields, named alike.
PRESET_KEYS: tuple[str, ...] = ("flow_yield_cv", "flow_noise_sd", "flow_background",
                                "well_noise_cv", "homopolymer_yield_loss", "empty_flow_law",
                                "empty_flow_mean", "empty_flow_sd")


def preset_values(name: str) -> dict[str, float | str]:
    """The ``[assay]`` values of preset ``name`` (a KeyError naming the allowed ones if none)."""
    if name not in PRESETS:
        raise KeyError(f"chemistry {name!r}: must be one of {', '.join(PRESET_NAMES)}")
    model = PRESETS[name]
    return {k: getattr(model, k) for k in PRESET_KEYS}

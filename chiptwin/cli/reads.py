"""``chiptwin reads call FILE``: a measured flowgram file (SFF, BAM) called by the twin's
callers, beside the instrument's own calls (:mod:`chiptwin.report.reads_call`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from chiptwin.cli.common import _shown, _working
from chiptwin.cli.progress import Progress as _Progress
from chiptwin.cli.text import table
from chiptwin.config import ScenarioError

READS_HELP = ("call a measured flowgram file's reads (SFF from 454, BAM from Ion Torrent) with "
              "the twin's callers, beside the instrument's own calls")


def add_reads(r: argparse.ArgumentParser) -> None:
    """The command's arguments."""
    r.add_argument("action", choices=["call", "profile"],
                   help="call: call every read of FILE; profile: fit the flow-value model to "
                   "the measured flow-value distributions in the folder FILE and compare the "
                   "[assay] chemistry presets with them")
    r.add_argument("file", metavar="FILE", help="call: an SFF file (needs the [sff] extra) or a "
                   "BAM with flow signals, aligned or not (needs the [bam] extra); profile: the "
                   "real-data folder holding flow_profiles/ (454 FLX and Titanium) and ion/ "
                   "(the Ion BAM)")
    r.add_argument("--twin", action="store_true", help="profile: also run the bundled scene "
                   "pyro_454_flx, as bundled and with no phasing, and compare its phase-corrected "
                   "values (a few minutes)")
    r.add_argument("--truth", metavar="FASTA", help="the template of each read after the key, "
                   "one record per read named as in FILE (an aligned BAM's truth is the "
                   "reference under each read, rebuilt from CIGAR and MD)")
    r.add_argument("--caller", choices=["round", "dephase"], default="round",
                   help="round each flow value, or the phase-correcting caller (default round)")
    r.add_argument("--first", type=int, metavar="N", help="call only the first N reads")
    r.add_argument("--out", help="output folder (default: out/FILE_STEM-reads)")
    r.add_argument("--quiet", action="store_true", help="no progress, no table")


def reads_command(args: argparse.Namespace) -> int:
    if args.action == "profile":
        return profile_command(args)
    from chiptwin.config.outputs import check_out_dir, output_lock
    from chiptwin.report.reads_call import JSON_NAME, call_file, write_reads_outputs
    from chiptwin.report.reads_markdown import headline

    path = Path(args.file)
    if not path.is_file():
        raise ScenarioError("chiptwin", "FILE", args.file, "must be an SFF or BAM file")
    if args.first is not None and args.first < 1:
        raise ScenarioError("chiptwin", "--first", args.first, "must be 1 or more")
    if args.truth is not None and not Path(args.truth).is_file():
        raise ScenarioError("chiptwin", "--truth", args.truth, "must be a FASTA file")
    out = check_out_dir(args.out or Path("out") / f"{path.stem}-reads", marker=JSON_NAME)
    progress = None if args.quiet else _Progress("reads")
    with output_lock(out), _working(progress):
        result = call_file(path, args.truth, args.caller, progress=progress, first=args.first)
        out = write_reads_outputs(result, out)
    if not args.quiet:
        print(table(headline(result.summary)))
        print(table([("outputs in", f"{_shown(out)}/ (reads.fastq, reads.sff, report.md, "
                                    f"{JSON_NAME})")]))
    return 0


def profile_command(args: argparse.Namespace) -> int:
    """``chiptwin reads profile DATA``: the flow-value model fitted to the measured sets, the
    presets' distances per length, the figure (:mod:`chiptwin.report.flow_profile`)."""
    import numpy as np

    from chiptwin.config.outputs import check_out_dir, output_lock
    from chiptwin.report.flow_profile import (
        between_454,
        chemistry_report,
        measured_sets,
        sff_checks,
    )
    from chiptwin.report.flow_profile_out import JSON_NAME, twin_checks, write_outputs

    data = Path(args.file)
    if not data.is_dir():
        raise ScenarioError("chiptwin", "FILE", args.file,
                            "must be the real-data folder (flow_profiles/, ion/) for profile")
    out = check_out_dir(args.out or Path("out") / "flow-profile", marker=JSON_NAME)
    progress = None if args.quiet else _Progress("profile")
    with output_lock(out), _working(progress):
        sets = measured_sets(data)
        rng = np.random.default_rng(0)  # the sampling floors' draws
        reports = [chemistry_report(name, source, measured, law,
                                    rng if name == "ion_pgm" else None)
                   for name, source, measured, law in sets]
        profiles = {r.name: r.measured for r in reports}
        between = between_454(profiles["454_flx"], profiles["454_titanium"])
        sffs = sff_checks(data)
        twins = twin_checks(profiles["454_flx"]) if args.twin else []
        out = write_outputs(out, reports, between, twins, sffs)
    if not args.quiet:
        print("TV per true length   0-mer  1-mer  2-mer  3-mer  4-mer  5-mer")
        lines = [("454_flx preset", [r.tv_preset for r in reports[0].rows]),
                 ("FLX vs Titanium", [tv for _, tv, _ in between]),
                 ("454_titanium preset", [r.tv_preset for r in reports[1].rows]),
                 ("ion_pgm preset", [r.tv_preset for r in reports[2].rows]),
                 ("ion sampling floor", [r.tv_floor or 0.0 for r in reports[2].rows])]
        for label, tvs in lines:
            print(f"{label:<20}" + "".join(f"{tv:7.3f}" for tv in tvs))
        for c in sffs:
            print(f"{Path(c.path).name} ({c.chemistry}, {c.flows} flows): TV to the 454_flx "
                  f"mixture {c.tv['454_flx']:.3f}, to 454_titanium {c.tv['454_titanium']:.3f}")
        for twin in twins:
            print(f"twin run {twin.scene} ({twin.variant}), TV to FLX: " + ", ".join(
                f"{row['length']}-mer {row['tv_to_measured']:.3f}" for row in twin.rows))
        print(table([("outputs in", f"{_shown(out)}/ (report.md, flow_profiles.png, "
                                    f"{JSON_NAME})")]))
    return 0

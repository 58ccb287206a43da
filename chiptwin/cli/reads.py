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
    r.add_argument("action", choices=["call"], help="call: call every read of FILE")
    r.add_argument("file", metavar="FILE", help="an SFF file (needs the [sff] extra) or a BAM "
                   "with flow signals, aligned or not (needs the [bam] extra)")
    r.add_argument("--truth", metavar="FASTA", help="the template of each read after the key, "
                   "one record per read named as in FILE (an aligned BAM's truth is the "
                   "reference under each read, rebuilt from CIGAR and MD)")
    r.add_argument("--caller", choices=["round", "dephase"], default="round",
                   help="round each flow value, or the phase-correcting caller (default round)")
    r.add_argument("--first", type=int, metavar="N", help="call only the first N reads")
    r.add_argument("--out", help="output folder (default: out/FILE_STEM-reads)")
    r.add_argument("--quiet", action="store_true", help="no progress, no table")


def reads_command(args: argparse.Namespace) -> int:
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

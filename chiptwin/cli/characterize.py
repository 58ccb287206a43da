"""``chiptwin characterize``: the EMVA 1288 bench of a scenario's chip, the IEEE 1241 bench of
its converters (``--adc``), or a camera's measured data set (``--measured``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from chiptwin.cli.common import _scenario_path, _shown, _working
from chiptwin.cli.progress import Progress as _Progress
from chiptwin.cli.text import fit
from chiptwin.config import ScenarioError, load_scenario
from chiptwin.config.catalog import bundled_scenarios_folder

CHARACTERIZE_HELP = ("EMVA 1288 datasheet of a scenario's chip, of the twin a datasheet "
                     "configures, or of a camera's measured data set")


def add_characterize(ch: argparse.ArgumentParser) -> None:
    """The command's arguments."""
    ch.add_argument("scenario", nargs="?", help="a TOML file, or the name of a bundled scenario "
                    "(default with --from: pyro_1fmol)")
    ch.add_argument("--from", dest="from_datasheet", metavar="FILE.json",
                    help="configure the chip's pixel and ADC from this datasheet (a file, or "
                    "the name of a bundled one) first")
    ch.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a scenario value (repeatable)")
    ch.add_argument("--seed", type=int, help="replace scenario.seed")
    ch.add_argument("--out", help="output folder (default: out/SCENARIO_NAME-emva1288, "
                    "with --adc out/SCENARIO_NAME-adc1241)")
    ch.add_argument("--adc", action="store_true", help="the ADC's own IEEE 1241 bench instead: "
                    "every converter as built, driven at its input (adc1241.json)")
    ch.add_argument("--adc-dnl-sigma", type=float, default=0.1, metavar="LSB",
                    help="with --adc: the DNL's standard error asked (default 0.1 LSB)")
    ch.add_argument("--adc-converters", type=int, default=256, metavar="N",
                    help="with --adc: most converters measured, a grid over the array "
                    "(default 256)")
    ch.add_argument("--measured", metavar="DIR",
                    help="a camera's EMVA 1288 data set instead of a scenario (a folder with "
                         "EMVA1288_Data.txt and its images): the same datasheet from measured "
                         "images")
    ch.add_argument("--pixel-pitch-um", type=float, metavar="UM",
                    help="with --measured: the camera's pixel pitch (a data set does not carry "
                         "it), for the per-area figures and --write-scenario")
    ch.add_argument("--write-scenario", metavar="OUT.toml",
                    help="with --measured: write the camera's twin as a scenario, read it "
                         "through the data set's protocol and lay its curves over the measured "
                         "ones (overlay.png)")
    ch.add_argument("--write-measured", metavar="DIR",
                    help="with a SCENARIO: also write the twin's protocol as an EMVA 1288 data "
                         "set (single-frame images, as the format has one image size)")
    ch.add_argument("--quiet", action="store_true", help="no progress, no table")


def characterize_command(args: argparse.Namespace) -> int:
    from chiptwin.characterize import characterize
    from chiptwin.characterize.outputs import JSON_NAME, headline
    from chiptwin.config.outputs import check_out_dir, output_lock

    if args.measured is not None:
        return _characterize_measured(args)
    for flag in ("pixel_pitch_um", "write_scenario"):
        if getattr(args, flag) is not None:
            raise ScenarioError("chiptwin", "--" + flag.replace("_", "-"), getattr(args, flag),
                                "is only for --measured DIR (a camera's data set)")
    if args.scenario is None and args.from_datasheet is None:
        raise ScenarioError("chiptwin", "characterize", "(nothing)",
                            "needs a SCENARIO, --from FILE.json, or both (or --measured DIR)")
    path = _scenario_path(args.scenario or "pyro_1fmol")
    datasheet = args.from_datasheet
    if datasheet:
        from chiptwin.config.datasheet import bundled_datasheet
        from chiptwin.config.load import load_with_datasheet

        datasheet = bundled_datasheet(datasheet, bundled_scenarios_folder() / "datasheets")
        scenario = load_with_datasheet(path, datasheet, args.set, args.seed)
    else:
        scenario = load_scenario(path, args.set, args.seed)
    if args.adc:
        return _characterize_adc(scenario, args)
    out = check_out_dir(args.out or Path("out") / f"{scenario.scenario.name}-emva1288",
                        marker=JSON_NAME)  # before the measurement
    protocol = None
    if args.write_measured:
        from chiptwin.characterize.export import single_frame_protocol
        from chiptwin.config.outputs import check_out_dir as check

        check(args.write_measured, marker="EMVA1288_Data.txt")
        protocol = single_frame_protocol()
    progress = None if args.quiet else _Progress("images")
    with output_lock(out), _working(progress):
        result = characterize(scenario, protocol, progress=progress, datasheet_in=datasheet,
                              keep_images=bool(args.write_measured))
        out = result.write(out)
        if args.write_measured:
            from chiptwin.characterize.export import write_measured

            written = write_measured(result.datasheet.measurement, args.write_measured,
                                     scenario.scenario.name)
    if not args.quiet:
        print(fit(headline(result.datasheet)))
        print(f"  outputs in {_shown(out)}/ ({JSON_NAME}, datasheet.md, plots)")
        if args.write_measured:
            print(f"  the protocol as an EMVA 1288 data set in {_shown(written)}/")
    return 0


def _characterize_measured(args: argparse.Namespace) -> int:
    """``characterize --measured DIR``: a camera's data set through the same evaluation."""
    from chiptwin.characterize.measured import characterize_measured
    from chiptwin.characterize.outputs import JSON_NAME, headline
    from chiptwin.config.outputs import check_out_dir, output_lock

    for flag in ("scenario", "from_datasheet", "write_measured", "seed"):
        if getattr(args, flag) is not None or (flag == "scenario" and args.set):
            raise ScenarioError("chiptwin", "--measured", args.measured,
                                "reads a camera's data set: it takes no SCENARIO, --from, --set, "
                                "--seed or --write-measured")
    if args.adc:
        raise ScenarioError("chiptwin", "--adc", True, "measures a scenario's converters, not "
                            "a camera's data set: drop --measured or --adc")
    folder = Path(args.measured)
    out = check_out_dir(args.out or Path("out") / f"{folder.resolve().name}-emva1288",
                        marker=JSON_NAME)
    if args.write_scenario is not None and args.pixel_pitch_um is None:
        raise ScenarioError("chiptwin", "--pixel-pitch-um", None,
                            "is needed with --write-scenario: a data set gives photons per "
                            "pixel, not the pixel's size")
    progress = None if args.quiet else _Progress("images")
    with output_lock(out), _working(progress):
        result = characterize_measured(folder, args.pixel_pitch_um, progress=progress)
        if args.write_scenario is not None:
            from chiptwin.characterize.camera_twin import replay_twin

            replay_twin(result, args.write_scenario)
        out = result.write(out)
    if not args.quiet:
        print(fit(headline(result.datasheet)))
        if args.write_scenario is not None:
            print("  the twin through the data set's protocol, largest residual below "
                  "saturation:")
            print(fit([f"    {line}" for line in result.meta["twin"]["findings"]]))
            print(f"  scenario written to {_shown(Path(args.write_scenario))}")
        print(f"  outputs in {_shown(out)}/ ({JSON_NAME}, datasheet.md, plots)")
    return 0


def _characterize_adc(scenario, args: argparse.Namespace) -> int:
    from chiptwin.characterize.adc1241.bench import BenchSettings, adc_bench
    from chiptwin.characterize.adc1241.outputs import JSON_NAME, headline
    from chiptwin.config.outputs import check_out_dir

    try:
        settings = BenchSettings(dnl_sigma_lsb=args.adc_dnl_sigma,
                                 max_converters=args.adc_converters)
    except ValueError as exc:
        dnl = str(exc).startswith("dnl_sigma_lsb")
        raise ScenarioError("chiptwin", "--adc-dnl-sigma" if dnl else "--adc-converters",
                            args.adc_dnl_sigma if dnl else args.adc_converters,
                            str(exc).split(": ", 1)[-1]) from None
    out = check_out_dir(args.out or Path("out") / f"{scenario.scenario.name}-adc1241",
                        marker=JSON_NAME)  # before the measurement
    progress = None if args.quiet else _Progress("conversions")
    with _working(progress):
        bench = adc_bench(scenario, settings=settings, progress=progress)
    out = bench.write(out)
    if not args.quiet:
        print(fit(headline(bench.to_json())))
        print(f"  {bench.wall_time_s:.1f} s; outputs in {_shown(out)}/ ({JSON_NAME}, adc1241.npz, "
              "adc1241.md, plots)")
    return 0

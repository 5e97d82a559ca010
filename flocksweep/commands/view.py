"""``flocksweep view``: interactive 3-D viewer page (and GIF/MP4) of a run.

The options and the handler; the work is :mod:`flocksweep.analysis.viewer.command`."""
from __future__ import annotations

from pathlib import Path

from flocksweep.command import Command

HELP = "interactive 3-D viewer page (and GIF/MP4) of a run or of measured tracks"
DESCRIPTION = ("Write a self-contained 3-D viewer page (HTML, works offline) of a run: a model preset "
               "(simulated), a sweep run (re-simulated and checked bit for bit), a saved trajectory, a track "
               "file (any format flocksweep measure reads) or a flocksweep measure folder (a menu of its "
               "flocks); --animate also exports a GIF or MP4.")


def arguments(p) -> None:
    from flocksweep.analysis.viewer.palette import COLOR_MODES   # only when its options are declared
    from flocksweep.observables.track_names import FORMATS, ROLES

    from .measure import add_reading_options

    p.add_argument("source", help="model preset TOML, sweep results directory, trajectory .npz, a track file or "
                                  "folder (as flocksweep measure reads), or a flocksweep measure folder")
    sweep = p.add_argument_group("sweep runs (SOURCE is a results directory)")
    sweep.add_argument("--run", metavar="RUN_ID", nargs="+",
                       help="run id (or a unique prefix of >= 6 characters); several ids: one page with a run "
                            "menu, the URL fragment #run=ID picks the run shown")
    sweep.add_argument("--where", metavar='"KEY=VALUE, ..."',
                       help='parameter point, e.g. "perception.field_deg=60, init.n=100" (n = init.n)')
    sweep.add_argument("--replicate", type=int, default=0, help="replicate at the --where point (default 0)")
    sweep.add_argument("--showcase", metavar="NAME", help="an entry of the sweep's [report.showcase], e.g. sample1")
    model = p.add_argument_group("model presets (SOURCE is a model TOML)")
    model.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                       help="override a preset key (repeatable)")
    model.add_argument("--seed", type=int, help="run seed (default 0)")
    model.add_argument("--n", type=int, help="number of boids (init.n)")
    model.add_argument("--duration", type=float, help="simulated seconds (run.duration)")
    model.add_argument("--dt", type=float, help="time step in seconds (run.dt)")
    tracks = p.add_argument_group("measured tracks (SOURCE is a track file or folder, or a measure folder)")
    tracks.add_argument("--flock", metavar="NAME", help="show this flock only (default: every flock, a menu "
                                                        "switches between them; --animate needs one)")
    tracks.add_argument("--group-radius", type=float, metavar="R",
                        help="links individuals into groups (analysis length units; default: the measure "
                             "folder's, else 20, said so in the page)")
    add_reading_options(tracks, FORMATS, ROLES, fps_flag="--tracks-fps")
    tracks.add_argument("--interval", type=float, metavar="S",
                        help="resample onto this interval (default: each flock's own sampling interval)")
    tracks.add_argument("--max-gap", type=float, metavar="S", help="bridge gaps up to S seconds (default 2.5 "
                                                                   "intervals)")
    tracks.add_argument("--velocity-interval", metavar="S|recorded",
                        help="difference positions over S seconds, or 'recorded' (default: recorded when the "
                             "file has velocities, else one interval)")
    page = p.add_argument_group("page and animation")
    page.add_argument("--out", type=Path, metavar="PAGE.html",
                      help="page path (default: results/view/<model>-seed<S>.html for a model, "
                           "RESULTS_DIR/viewer/<run or showcase>.html for a sweep run, the .npz path with "
                           ".html for a trajectory)")
    page.add_argument("--color-by", choices=("auto",) + COLOR_MODES, default="auto",
                      help="initial colouring (switchable in the page; auto: pattern in pattern mode, leader "
                           "with change of leadership, else boid)")
    page.add_argument("--start-time", type=float, metavar="SECONDS",
                      help="the simulated second the page opens at (default: the start; the page's URL can also "
                           "say it: PAGE.html#t=15&color=group)")
    page.add_argument("--trail", type=float, default=2.0, metavar="SECONDS", help="trail length (default 2 s)")
    page.add_argument("--max-mb", type=float, default=5.0, help="page size cap: frames are thinned to fit (default 5)")
    page.add_argument("--stride", type=int, help="keep every K-th recorded step (overrides --max-mb)")
    page.add_argument("--animate", type=Path, metavar="OUT.gif|OUT.mp4", help="also write an animation")
    page.add_argument("--no-page", action="store_true", help="with --animate: write only the animation")
    page.add_argument("--fps", type=float, default=20.0, help="animation frames per second (default 20)")
    page.add_argument("--speed", type=float, default=1.0, help="simulated seconds per second of animation")
    page.add_argument("--rotate", action="store_true", help="animation camera turns slowly about the vertical")
    page.add_argument("--size", default="640x480", metavar="WxH",
                      help="animation size in pixels, 16 to 3840 a side (default 640x480)")
    page.add_argument("--dpi", type=int, default=100, help="animation dots per inch (text size; default 100)")
    page.add_argument("--no-progress", action="store_true",
                      help="no progress on stderr (the phases as they start, the animation's frames)")


def handler(args) -> int:
    from flocksweep.analysis.viewer.command import run

    from .measure import reading_given

    args.reading = reading_given(args)
    return run(args)


COMMAND = Command("view", HELP, DESCRIPTION, arguments, handler)

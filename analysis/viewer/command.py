"""``flocksweep view``: the viewer page (and optionally an animation) of a run from any source.

    flocksweep view MODEL.toml [--set KEY=VALUE ...] [--seed S] [--n N] [--duration T] [--dt DT]
    flocksweep view RESULTS_DIR (--run RUN_ID [RUN_ID ...] | --where "KEY=VALUE, ..." [--replicate K] | --showcase NAME)
    flocksweep view TRAJECTORY.npz
    flocksweep view TRACKS [--format ...] [--layout ...] [--columns ...] [--units ...] [--tracks-fps HZ] [...]
                           [--interval S] [--velocity-interval S|recorded] [--flock NAME] [--group-radius R]
    flocksweep view MEASURE_FOLDER [--flock NAME] [--group-radius R]
      common: [--out PAGE.html] [--animate OUT.gif|OUT.mp4] [--no-page] [--color-by MODE] [--trail SECONDS]
              [--max-mb MB] [--stride K] [--fps F] [--speed X] [--rotate] [--size WxH] [--dpi D]

A model preset is simulated (seed 0 unless ``--seed``); a sweep run is re-simulated from its stored spec
and seed and must reproduce its stored results bit for bit (:mod:`analysis.viewer.resimulate`), or
nothing is written; a trajectory is shown as saved (with its ``params.json`` or its sweep's spec when
found). A track file (any file or folder ``flocksweep measure`` reads, with its reading options; ``--fps``
of measure is ``--tracks-fps`` here) and a measure folder (its ``measure.json`` says which file and how it
was read) are read, checked and resampled as ``measure`` does (:func:`observables.measured.observe_tracks`),
each flock shown with its gaps interpolated (:func:`analysis.viewer.track.from_observed`); several flocks
make one page with a menu (``#run=NAME``), ``--flock`` picks one (an animation needs one). 2-D tracks are
seen from above, in the page and in the animation. Several ``--run`` ids make one page of several runs with a run menu (each re-simulated and
checked; the URL fragment ``#run=ID`` picks the run shown; the size cap holds for the whole page).
Default page path: ``results/view/<model>-seed<S>.html``, ``RESULTS_DIR/viewer/<run or
showcase>.html`` (``runs-<first id>-and-<K>-more.html`` for several runs), or the trajectory's path with
``.html``. The command is declared in
``flocksweep/commands/view.py``; its handler calls :func:`run`.
"""
from __future__ import annotations

import sys
from pathlib import Path

from flocksweep.simcore.schema import ConfigError
from flocksweep.sweeps.progress import Phases, next_steps



TRACK_SUFFIXES = (".csv", ".gz", ".tsv", ".txt", ".parquet", ".pq", ".mat", ".npy", ".h5")


def _kind(source: Path, reading: dict | None = None) -> str:
    if source.is_dir():
        if (source / "measure.json").is_file():
            return "measured"
        if reading or not ((source / "design.parquet").exists() or (source / "manifest.json").exists()) and any(
                p.suffix.lower() in (".npz", ".csv") for p in source.iterdir()):
            return "tracks"
        return "sweep"
    if not source.exists():
        raise ConfigError("source", f"{source}: no such file or directory")
    if reading and reading.get("format"):
        return "tracks"
    if source.suffix == ".npz":
        return "trajectory" if _is_trajectory(source) else "tracks"
    if source.suffix.lower() in TRACK_SUFFIXES:
        return "tracks"
    if source.suffix == ".toml":
        from flocksweep.simcore.params import read_toml

        data = read_toml(source)
        if "axes" in data or isinstance(data.get("model"), dict):
            name = data.get("name", "NAME")
            raise ConfigError("source", f"{source} is a sweep file; view one of its runs from its results "
                                        f"directory, e.g. flocksweep view results/{name} --run RUN_ID")
        return "model"
    raise ConfigError("source", f"{source}: expected a model preset .toml, a sweep results directory, a trajectory "
                                "or tracks .npz, a track file (csv, parquet, mat, npy; --format names another) or a "
                                "flocksweep measure folder")


def _is_trajectory(path: Path) -> bool:
    """A flocksweep trajectory .npz (times, pos and vel), not a tracker's arrays (idtracker.ai, TRex)."""
    from flocksweep.observables.npy_file import npz_headers
    try:
        keys = npz_headers(path)
    except ValueError:
        return True          # not an archive at all: the trajectory reader names what is wrong
    return {"times", "pos", "vel"} <= set(keys) or not ({"trajectories", "X", "Y"} & set(keys))


def _check_flags(args, kind: str) -> None:

    sweep_flags = {"--run": args.run, "--where": args.where, "--showcase": args.showcase,
                   "--replicate": args.replicate or None}
    model_flags = {"--set": args.overrides or None, "--seed": args.seed, "--n": args.n,
                   "--duration": args.duration, "--dt": args.dt}
    reading = {"--" + key.replace("_", "-"): value for key, value in (getattr(args, "reading", None) or {}).items()}
    track_flags = {"--flock": args.flock, "--group-radius": args.group_radius}
    file_flags = {**reading, "--interval": args.interval, "--max-gap": args.max_gap,
                  "--velocity-interval": args.velocity_interval}
    wheres = {"sweep": "a sweep results directory", "model": "a model preset TOML",
              "tracks": "a track file or folder", "tracks or measured": "a track file or a measure folder"}
    for flags, only in ((sweep_flags, "sweep"), (model_flags, "model"), (file_flags, "tracks"),
                        (track_flags, "tracks or measured")):
        for flag, value in flags.items():
            if value is not None and kind not in only.split(" or "):
                raise ConfigError(flag, f"only applies when SOURCE is {wheres[only]} (got a {kind} source"
                                        + (": a measure folder reads its tracks as it measured them)"
                                           if kind == "measured" and only == "tracks" else ")"))
    if not 0 <= args.trail < float("inf"):
        raise ConfigError("--trail", f"got {args.trail}; expected a number of seconds >= 0")
    if args.start_time is not None and not 0 <= args.start_time < float("inf"):
        raise ConfigError("--start-time", f"got {args.start_time}; expected a number of seconds >= 0")
    if args.run and len(args.run) > 1 and args.animate:
        raise ConfigError("--animate", "animates one run; got several --run ids (give one, or drop --animate)")
    if args.no_page and not args.animate:
        raise ConfigError("--no-page", "only with --animate (otherwise nothing would be written)")
    if args.replicate < 0:
        raise ConfigError("--replicate", f"got {args.replicate}; must be an integer >= 0")


def _size(text: str) -> tuple[int, int]:

    from .animation import MAX_SIDE

    width, sep, height = text.lower().partition("x")
    if not (sep and width.isdigit() and height.isdigit()):
        raise ConfigError("--size", f"got {text!r}; expected WIDTHxHEIGHT in pixels, e.g. 640x480")
    if not all(16 <= int(side) <= MAX_SIDE for side in (width, height)):
        raise ConfigError("--size", f"got {text!r}; each side must be from 16 to {MAX_SIDE} pixels")
    return int(width), int(height)


def _model_track(args):

    from flocksweep.simcore import load_preset, simulate_preset
    from flocksweep.sweeps.budget import check_runs

    from .resimulate import record_step_for
    from .track import from_observations

    overrides = list(args.overrides)
    for flag, key in ((args.n, "init.n"), (args.duration, "run.duration"), (args.dt, "run.dt")):
        if flag is not None:
            overrides.append(f"{key}={flag!r}")
    preset = load_preset(args.source, overrides)
    seed = 0 if args.seed is None else args.seed
    if seed < 0:
        raise ConfigError("--seed", f"got {seed}; must be an integer >= 0")
    step = record_step_for(preset.run.n_steps, preset.init.n)
    check_runs("init.n", preset.init.n, preset.run.n_steps, step)   # before simulating: memory for this flock
    obs = simulate_preset(preset, seed, step)
    info = {"model": str(args.source), "seed": seed, "overrides": ", ".join(overrides) or "none"}
    track = from_observations(obs, preset, title=f"{preset.model.name}: N = {obs.n}, seed {seed}", info=info)
    return track, Path("results") / "view" / f"{preset.model.name}-seed{seed}.html"


def _sweep_track(args, run_id=None):
    from .resimulate import parse_where, record_step_for, reproduce, select_run
    from .hooks import run_steps, slug
    from .track import from_observations

    where = parse_where(args.where) if args.where is not None else None
    row = select_run(args.source, run_id, where, args.replicate, args.showcase)
    reproduced = reproduce(args.source, row, record_step_for(*run_steps(args.source, row)))
    checked = int(reproduced.checks["identical"].sum())
    print(f"run {row['run_id']} (seed {int(row['seed'])}, replicate {int(row['replicate'])}) re-simulated: "
          f"reproduces its stored results bit for bit ({checked} checks)")
    info = {"sweep": args.source.resolve().name, "run id": row["run_id"], "replicate": int(row["replicate"]),
            "seed": int(row["seed"]), "reproduced": f"bit for bit ({checked} checks)"}
    if args.showcase:
        info["showcase"] = args.showcase
    name = args.showcase or row["run_id"]
    track = from_observations(reproduced.obs, reproduced.preset, info=info, group_radius=reproduced.group_radius,
                              title=f"{args.source.resolve().name}: {name}")
    return track, args.source / "viewer" / f"{slug(name)}.html"


def _flocks_page(args, tracks, names, default, phases) -> int:
    """One page of several measured flocks with a menu (the URL fragment #run=NAME picks one)."""
    from .page import MB, build_runs_page

    if args.no_page:
        raise ConfigError("--no-page", "an animation shows one flock: name it with --flock")
    phases.start(f"building the page of {len(tracks)} flocks")
    page = build_runs_page(tracks, names, max_mb=args.max_mb, stride=args.stride, color_by=args.color_by,
                           trail_s=args.trail, start_time=args.start_time)
    path = page.save(args.out or default)
    print(f"  wrote {path} ({page.size_bytes / MB:.2f} MB; {len(tracks)} flocks, a menu switches between them; "
          f"PAGE#run=NAME opens one); open it in a browser, it works offline")
    return 0


def _runs_page(args, phases) -> int:
    """One page of the several ``--run`` runs of a sweep (each re-simulated and checked)."""
    from .hooks import slug
    from .page import MB, build_runs_page

    tracks = [_sweep_track(args, run_id)[0] for run_id in args.run]
    ids = [str(t.info["run id"]) for t in tracks]
    if len(set(ids)) != len(ids):
        raise ConfigError("--run", f"names a run twice ({', '.join(args.run)} are the runs {', '.join(ids)})")
    phases.start(f"building the page of {len(ids)} runs")
    page = build_runs_page(tracks, ids, max_mb=args.max_mb, stride=args.stride, color_by=args.color_by,
                           trail_s=args.trail, start_time=args.start_time)
    default = args.source / "viewer" / f"runs-{slug(ids[0])}-and-{len(ids) - 1}-more.html"
    path = page.save(args.out or default)
    print(f"  wrote {path} ({page.size_bytes / MB:.2f} MB; {len(ids)} runs, a menu switches between them; "
          f"PAGE#run=ID opens one); open it in a browser, it works offline")
    next_steps(f"open {path} in a browser ({path.name}#run={ids[-1]} opens the last run)")
    return 0


def _track_settings(args, kind: str):
    """(the track file, how to read it, interval, max_gap, velocity interval, group radius, default page
    folder) of a track source: the command line's, or for a measure folder what its measure.json recorded."""
    import json

    from flocksweep.observables.tracks import TrackSource, track_source

    source = Path(args.source)
    if kind == "tracks":
        velocity = args.velocity_interval
        if velocity is not None and velocity != "recorded":
            try:
                velocity = float(velocity)
            except ValueError:
                raise ConfigError("--velocity-interval", f"got {velocity!r}; expected seconds or 'recorded'") from None
        return (source, track_source(source, args.reading, ""), args.interval, args.max_gap,
                "auto" if velocity is None else velocity, args.group_radius,
                Path("results") / "view" / source.name.split(".")[0])
    try:
        info = json.loads((source / "measure.json").read_text())
        reading = info["reading"]
        path = Path(info["tracks"])
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ConfigError("source", f"{source / 'measure.json'} cannot be read as a measure folder's record ({err}); "
                                    "measure the tracks again with flocksweep measure") from None
    if not path.exists():
        raise ConfigError("source", f"{source}: its tracks {path} are gone; view the file where it is now "
                                    "(flocksweep view TRACKS with the reading options of measure.json)")
    radius = args.group_radius if args.group_radius is not None else info.get("group_radius")
    return (path, TrackSource(**{k: v for k, v in reading.items() if v is not None}), info.get("interval_given"),
            info.get("max_gap_given"), info.get("velocity_interval", "auto"), radius, source / "viewer")


def _track_pages(args, kind: str, phases) -> tuple[list, list, Path]:
    """(the Tracks of the measured flocks, their names, the default page path)."""
    from flocksweep.observables.measured import observe_tracks
    from flocksweep.observables.tracks import load_tracks
    from flocksweep.observables.validation import TrackError, describe

    from .hooks import slug
    from .track import from_observed

    path, source, interval, max_gap, velocity, radius, folder = _track_settings(args, kind)
    try:
        table = load_tracks(path, source)
        flocks, issues = observe_tracks(table, interval, max_gap, velocity)
    except TrackError as err:
        raise ValueError(f"{err}\n  (flocksweep measure {path} lists every problem in validation.csv)") from None
    for issue in [i for i in issues if i.level == "error"][:5]:
        print(f"flocksweep: {describe(issue, table.line_offset)}", file=sys.stderr)
    names = [str(f.name) for f in flocks]
    if args.flock is not None:
        if args.flock not in names:
            raise ConfigError("--flock", f"got {args.flock!r}; {path.name} holds the flocks {', '.join(names)}")
        flocks = [f for f in flocks if str(f.name) == args.flock]
    if not flocks:
        raise ValueError(f"{path}: no flock could be resampled (flocksweep measure {path} says why)")
    if args.animate and len(flocks) > 1:
        raise ConfigError("--animate", f"animates one flock; {path.name} holds {len(flocks)} ({', '.join(names[:6])}"
                                       f"{' ...' if len(names) > 6 else ''}): name one with --flock")
    info = {"source": path.name, "format": table.source.format, "lengths in": table.unit_label}
    tank = table.source.tank()      # the tank the tracks declare, drawn around them
    if tank is not None:
        info["tank"] = "declared by the tracks, drawn as a wireframe"
    tracks = [from_observed(f, title=f"{path.name}: flock {f.name}", info={**info, "flock": str(f.name)},
                            group_radius=radius, tank=tank) for f in flocks]
    name = slug(flocks[0].name) if len(flocks) == 1 else "flocks"
    default = folder / f"{name}.html" if kind == "measured" else folder.parent / f"{folder.name}-{name}.html"
    return tracks, [str(f.name) for f in flocks], default
def after_view(args, page, seconds: float = 0.0) -> list[str]:
    """Open what was written (``seconds``: the run's length, for an address that opens it half-way);
    offer the animation when only a page was."""
    steps = []
    if page is not None:
        middle = f"{seconds / 2:.3g}"
        steps.append(f"open {page} in a browser (works offline; {Path(page).name}#t={middle}&color=group opens it "
                     f"at {middle} s coloured by group)")
    if args.animate:
        steps.append(f"open {args.animate}")
    elif page is not None:
        steps.append(f"flocksweep view {' '.join(_source_words(args))} --animate {Path(page).stem}.gif --no-page   "
                     f"(a GIF beside the page)")
    return steps


def _source_words(args) -> list[str]:
    """The words naming this run on the command line (source and run selection)."""
    import shlex

    words = [str(args.source)]
    if args.showcase:
        words += ["--showcase", args.showcase]
    elif args.run:
        words += ["--run", *args.run]
    elif args.where:
        words += ["--where", args.where, "--replicate", str(args.replicate)]
    words += [f"--set={item}" for item in getattr(args, "overrides", []) or []]
    for flag in ("seed", "n", "duration", "dt"):
        if getattr(args, flag, None) is not None:
            words += [f"--{flag}", str(getattr(args, flag))]
    return [shlex.quote(word) for word in words]


def run(args) -> int:

    from .animation import AnimationUnavailable, check_options, ffmpeg_exe, write_animation
    from .page import MB, build_page
    from .resimulate import NotReproduced, RunNotFound
    from .track import from_npz

    source = Path(args.source)
    args.source = source
    kind = _kind(source, getattr(args, "reading", None))
    _check_flags(args, kind)
    size = _size(args.size)
    phases = Phases("view", 1 + (not args.no_page) + bool(args.animate), not args.no_progress)
    try:
        if args.animate and check_options(args.animate, args.fps, args.speed, size, args.dpi, args.color_by) == "mp4":
            ffmpeg_exe()  # before simulating: say now if MP4 cannot be written
        phases.start({"model": "simulating the run", "sweep": "re-simulating the run and checking it bit for bit",
                      "trajectory": "reading the trajectory", "tracks": "reading and resampling the tracks",
                      "measured": "reading and resampling the measured tracks"}[kind])
        if kind in ("tracks", "measured"):
            tracks, names, default = _track_pages(args, kind, phases)
            if len(tracks) > 1:
                return _flocks_page(args, tracks, names, default, phases)
            track = tracks[0]
        elif kind == "model":
            track, default = _model_track(args)
        elif kind == "sweep":
            if not (args.run or args.where or args.showcase):
                print("flocksweep: name the run to view: --run RUN_ID, --where \"KEY=VALUE, ...\" [--replicate K] "
                      "or --showcase NAME", file=sys.stderr)
                return 2
            if args.run and len(args.run) > 1:
                return _runs_page(args, phases)
            track, default = _sweep_track(args, args.run[0] if args.run else None)
        else:
            track, default = from_npz(source), source.with_suffix(".html")
        if args.animate and args.animate.parent == Path("."):   # a bare file name: beside the page, not here
            args.animate = Path(args.out or default).parent / args.animate.name
        if not args.no_page:
            phases.start("building the page")
            page = build_page(track, max_mb=args.max_mb, stride=args.stride, color_by=args.color_by,
                              trail_s=args.trail, start_time=args.start_time)
            path = page.save(args.out or default)
            print(f"  wrote {path} ({page.size_bytes / MB:.2f} MB; {page.n} boids, {page.frames} frames every "
                  f"{page.frame_interval:.3g} s, stride {page.stride}); open it in a browser, it works offline")
        if args.animate:
            phases.start(f"drawing the animation {args.animate.name} frame by frame")
            anim = write_animation(track, args.animate, color_by=args.color_by, fps=args.fps,
                                   speed=args.speed, rotate=args.rotate, trail_s=min(args.trail, 1.0),
                                   size=size, dpi=args.dpi, progress=not args.no_progress)
            print(f"  wrote {anim.path} ({anim.frames} frames at {anim.fps:g} fps, {anim.width}x{anim.height})")
        next_steps(*after_view(args, None if args.no_page else path, float(track.times[-1] - track.times[0])))
    except ConfigError:
        raise
    except (RunNotFound, NotReproduced, AnimationUnavailable, ValueError, FileNotFoundError) as err:
        print(f"flocksweep: {err}", file=sys.stderr)
        return 2
    return 0

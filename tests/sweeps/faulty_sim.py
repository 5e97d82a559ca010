#!/usr/bin/env python3
"""The example external simulator (configs/external/vicsek_sim.py) with a fault injected by ``--fault``:
``none`` (the simulator as it is), ``hang`` (sleeps far past any test's timeout, with a child process
that sleeps too), ``malformed`` (writes a
CSV without the track columns and exits 0), ``crash`` (a message on stderr, exit status 3), ``flood``
(``FLOOD_MIB`` MiB on stderr, default 64, then a last line, exit status 1) and ``daemon`` (starts a
background child that sleeps and would outlive it, then simulates and exits 0)."""
import os
import runpy
import subprocess
import sys
import time
from pathlib import Path

GRANDCHILD = "faulty-sim-grandchild"   # in the child's command line: tests look for it
DAEMON = "faulty-sim-daemon"           # the background child of ``daemon``
EXAMPLE = Path(__file__).resolve().parents[2] / "configs" / "external" / "vicsek_sim.py"

args = sys.argv[1:]
at = args.index("--fault")
fault = args[at + 1]
del args[at:at + 2]
if fault == "hang":   # and a child of its own, which a timeout must kill too
    subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)", GRANDCHILD])
    print("faulty_sim: hanging", file=sys.stderr, flush=True)
    time.sleep(600)
elif fault == "crash":
    print("faulty_sim: injected crash\nTraceback: none, on purpose", file=sys.stderr)
    sys.exit(3)
elif fault == "flood":
    line = b"x" * 1023 + b"\n"
    for _ in range(int(os.environ.get("FLOOD_MIB", "64")) * 1024):
        sys.stderr.buffer.write(line)
    sys.stderr.buffer.write(b"faulty_sim: the last line of the flood\n")
    sys.exit(1)
elif fault == "malformed":
    Path(args[args.index("--out") + 1]).write_text("agent,when\n1,2\n")
else:
    if fault == "daemon":   # a background child left running: the run's end must end it
        subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)", DAEMON], stdin=subprocess.DEVNULL,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    sys.argv = [str(EXAMPLE)] + args
    runpy.run_path(str(EXAMPLE), run_name="__main__")

"""Issue 27's figures in one run: whole calls against their kernels, POV-Ray, the peers.

    ./go python scripts/whole_call_timing.py [OUT.json]      # prints the tables; ~40 s

* warm ``mimarble.render`` at 500², 1 spp of fig11a with 8-octave marbles, with
  constant colours, and of the file itself (12 octaves), replay on and off
  (mimarble/bench/calls.py: whole call, its kernels, launches);
* a 64-frame period sweep at 256², 4 spp in this process, against its frames' kernels
  plus its first frame's compile;
* POV-Ray 3.7's own "Trace Time" for the same 8-octave sphere (mimarble/tools/povray.py;
  skipped when ``povray`` is not installed) over the warm ``mimarble.render`` call;
* one Adam step of notebook 02, traced and frozen (mimarble/bench/adam.py);
* the noise alone against the peers, one thread each (mimarble/bench/peers.py; a peer
  not installed is skipped: ``pip install mimarble[peers]``).

Every table names the machine. Medians; the machine is shared, so run it on a quiet one.
"""

import json
import sys
from pathlib import Path

import mimarble

mimarble.start()

from mimarble.bench import calls as bench_calls  # noqa: E402
from mimarble.bench.peers import peers_table  # noqa: E402
from mimarble.bench.report import calls_lines  # noqa: E402
from mimarble.runtime.machine import machine_facts, machine_line  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "scenes" / "fig11a.scene"


def main(out_json=None) -> int:
    machine = machine_line(machine_facts())
    calls = bench_calls.measure(SCENE)
    print(f"Machine: {machine}")
    print("\n".join(calls_lines({**calls, "peers": None})))
    print()
    print(peers_table(calls["peers"], machine))
    if out_json:
        Path(out_json).write_text(json.dumps({"machine": machine, **calls}, indent=1,
                                             default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:2]))

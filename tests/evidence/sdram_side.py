"""One side of the SDRAM evidence (test_sdram_evidence.py), run in a process whose imports
come from the tree given (the repository or a mutated copy).

``python sdram_side.py ROOT OUT.json SIZE``: renders the lit head (``SIZE``^3, view 30,20)
on VolumePro 500 with the cycle rung, its waveform on, and replays every SDRAM module's
command bus through ``sdram_checker`` on Icarus (:func:`rtl.sdram.replay.check_vcd`);
writes the summed checker counts, the cycle rung's counters and the violation lines.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path


def main(root: Path, out: Path, size: int) -> None:
    import hwsim
    import models
    import rtl

    for module in (hwsim, models, rtl):  # the tree given, not the venv's editable install
        path = Path(module.__file__).resolve()
        if not path.is_relative_to(root):
            raise SystemExit(f"{module.__name__} imported from {path}, not from {root}")
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "rtl"))  # top_cases
    from top_cases import scene_of

    from hwsim.run.fidelity import resolve_arch
    from hwsim.spec.transfer import resolve_transfer
    from hwsim.volumes import make_phantom
    from models.cycle import render_cycle
    from models.frame import frame_of
    from rtl.sdram.replay import check_vcd, device_of

    volume = make_phantom("head", size=size)
    scene = scene_of(30, 20, "lit", image=size)
    machine = resolve_arch("volumepro500")
    transfer = resolve_transfer(scene.transfer, volume)
    with tempfile.TemporaryDirectory() as tmp:
        vcd = Path(tmp) / "frame.vcd"
        result = render_cycle(frame_of(scene, volume, transfer, machine), trace=vcd)
        replays = check_vcd(vcd, device_of("volumepro500"), "icarus")
    counts = {k: sum(r.counts[k] for r in replays) for k in replays[0].counts}
    memory = {k: int(v) for k, v in result.counters.items() if k.startswith("memory.")}
    lines = [line for r in replays for line in r.violations]
    out.write_text(json.dumps({"counts": counts, "counters": memory, "violations": lines}))


if __name__ == "__main__":
    main(Path(sys.argv[1]).resolve(), Path(sys.argv[2]), int(sys.argv[3]))

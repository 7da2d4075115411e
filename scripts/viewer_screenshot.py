"""Screenshot of the Rerun viewer on a live foggy episode, taken without a display (the README's picture).

Logs ``--steps`` keyframes with :func:`fog_gym.viz.viewer.view_live`, opens the ``.rrd`` in Rerun's headless viewer,
moves to the last sample and saves a PNG. Needs the ``viz`` extra and a Vulkan driver; on a machine without a GPU,
Mesa's software one works (Debian/Ubuntu: ``apt install mesa-vulkan-drivers``).

    python scripts/viewer_screenshot.py --out docs/images/viewer.png --fog-tab dense
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="viewer_screenshot.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--town", default="highway", help="town (default highway)")
    parser.add_argument("--time-of-day", default="day", choices=("day", "night"), help="day or night (default day)")
    parser.add_argument("--steps", type=int, default=15, help="keyframes to log (default 15)")
    parser.add_argument("--seed", type=int, default=3, help="episode seed (default 3)")
    parser.add_argument("--resolution", default="640x480", help="camera resolution (default 640x480)")
    parser.add_argument("--fog-tab", default="dense", help="tab shown: clean, light, moderate or dense (default dense)")
    parser.add_argument("--wait", type=float, default=20.0, help="seconds the viewer gets to load and draw (default 20)")
    parser.add_argument("--out", type=Path, default=Path("docs/images/viewer.png"), help="PNG to write")
    args = parser.parse_args(argv)

    from rerun.experimental import ViewerClient

    from fog_gym.viz.viewer import view_live

    w, h = (int(v) for v in args.resolution.lower().split("x"))
    rrd = Path(tempfile.mkdtemp()) / "episode.rrd"
    levels = ["light", "moderate", "dense"]
    view_live(args.town, levels, args.steps, (w, h), args.time_of_day, args.seed, save=rrd, tab=args.fog_tab)
    os.environ.setdefault("WGPU_BACKEND", "vulkan")  # Mesa's software GL context fails in headless mode
    bin_dir = str(Path(sys.executable).parent)
    os.environ["PATH"] = bin_dir + os.pathsep + os.environ.get("PATH", "")
    if shutil.which("rerun") is None:
        raise SystemExit("viewer_screenshot.py: the rerun executable is missing (pip install 'fog-gym[viz]')")
    client = ViewerClient.spawn(headless=True, port=9891, hide_welcome_screen=True)
    try:
        client.open(str(rrd))
        client.set_time("sample_time", duration=(args.steps - 1) * 0.1)
        time.sleep(args.wait)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        shot = Path(tempfile.mkdtemp()) / "shot.png"
        client.save_screenshot(str(shot))
    finally:
        client.quit()
    import cv2

    img = cv2.imread(str(shot))
    if img.shape[1] > 1600:  # keep the README picture light
        img = cv2.resize(img, (1600, round(img.shape[0] * 1600 / img.shape[1])), interpolation=cv2.INTER_AREA)
    cv2.imwrite(str(args.out), img)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

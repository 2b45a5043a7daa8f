"""Screenshot and short GIF of ``strol-bench interact`` for the docs (run under Xvfb).

``xvfb-run -a -s "-screen 0 1024x768x24" python -m lab.study.capture_interact``

A scripted person drags the cup (30 N along +y for 1 s: the drag's point put where the mouse
would leave it, read after each ``sync``) on Task 1 with StROL; the screen is grabbed (Pillow,
XCB) every few control steps: the GIF, and one frame just after the correction is recorded.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import mujoco
import numpy as np
from PIL import Image, ImageGrab

from strol_gym.benchmarks.sessions import interact
from strol_gym.benchmarks.sessions.interact import DRAG_STIFFNESS

PUSH_START, PUSH_STEPS = 20, 20


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="docs/img", help="folder for the PNG and GIF (docs/img)")
    p.add_argument("--every", type=int, default=3, help="control steps between GIF frames")
    p.add_argument("--width", type=int, default=512, help="GIF width in pixels")
    args = p.parse_args()
    out = Path(args.out)
    frames: list[Image.Image] = []

    class ScriptedPerson(interact._Passive):
        def __init__(self, model, data):
            super().__init__(model, data)
            self.data, self.k, self.pushing = data, 0, False
            self.cup = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "cup")

        def sync(self):
            super().sync()
            self.pushing = PUSH_START <= self.k < PUSH_START + PUSH_STEPS
            self.k += 1

        def drag(self):
            d = super().drag()
            if not self.pushing:
                return d
            ref = self.data.site_xpos[self.cup] + np.array([0.0, 30.0, 0.0]) / DRAG_STIFFNESS
            translate = int(mujoco.mjtPertBit.mjPERT_TRANSLATE)
            return interact.Drag(d.select, translate, ref, d.refquat, d.localpos)

        def grab_window(self):
            """The viewer's window (at the screen's corner: Xvfb has no window manager)."""
            view = self.handle.viewport
            return ImageGrab.grab(bbox=(0, 0, view.width, view.height))

        def set_texts(self, texts):
            super().set_texts(texts)
            self.handle.set_texts(texts)  # this step's panel drawn before the grab
            super().sync()
            if self.k == PUSH_START + PUSH_STEPS + 12:  # after the 0.4 s hold-off
                self.grab_window().save(out / "interactive_panel.png")
            if self.k % args.every == 0:
                shot = self.grab_window()
                h = round(shot.height * args.width / shot.width)
                frames.append(
                    shot.resize((args.width, h)).convert("P", palette=Image.Palette.ADAPTIVE)
                )

    with tempfile.TemporaryDirectory() as folder:
        interact.run_interactive(
            task=1,
            log=Path(folder) / "s.jsonl",
            max_steps=PUSH_START + PUSH_STEPS + 40,
            realtime=False,  # grabbing the screen is slow; every step is synced and drawn
            viewer_factory=ScriptedPerson,
        )
    frames[0].save(
        out / "interactive.gif",
        save_all=True,
        append_images=frames[1:],
        duration=50 * args.every,
        loop=0,
        optimize=True,
    )
    print(f"wrote {out / 'interactive_panel.png'} and {out / 'interactive.gif'} ({len(frames)})")


if __name__ == "__main__":
    main()

"""A replay's processes: rviz on the user's display, or headless under Xvfb with screenshots.

Everything runs against a private ROS master (magna_common.ros_master.RosMaster, never 11311) with
/use_sim_time: the scene node (UAV markers, and the world relayed so its end-of-mission clearing is
dropped), rviz with the world family's configuration (camera fitted to the world and the flights),
and `rosbag play --clock`. Headless, an Xvfb server of its own (a free display, -displayfd) hosts
rviz, full screen with no panels, and Pillow grabs the screen every EVERY seconds of bag time (read
from rosbag play's own progress line) and once more when the picture has settled after the bag
ended. Every process started is ended, by process group, when the replay ends, fails or is
interrupted.
"""
from __future__ import annotations

import math
import os
import re
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
import xmlrpc.client
from collections.abc import Callable
from pathlib import Path
from typing import Any

from magna_common.files import write_atomically
from magna_common.ros_names import VIZ_BAG_WORLD, VIZ_SCENE, WORLD_MARKERS, ual
from magna_viz import rviz_config as rc
from magna_viz.replay.errors import ReplayFailure
from magna_viz.replay.media import write_gif, write_mp4
from magna_viz.replay.plan import FINAL_NAME, GIF_NAME, MP4_NAME, Plan

NODES_DIR = Path(__file__).resolve().parents[3] / "nodes"
PROGRESS = re.compile(rb"Duration:\s*([0-9.]+)\s*/\s*([0-9.]+)")  # rosbag play's progress line


class _Progress:
    """Reads rosbag play's output: its `Duration: elapsed / total` line gives the bag time played."""

    def __init__(self, stream):
        self.elapsed = 0.0
        self.tail = b""
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream) -> None:
        buffer = b""
        for chunk in iter(lambda: stream.read1(4096) if hasattr(stream, "read1") else stream.read(4096), b""):
            buffer = (buffer + chunk)[-4096:]
            found = PROGRESS.findall(buffer)
            if found:
                self.elapsed = max(self.elapsed, float(found[-1][0]))
            self.tail = buffer
        stream.close()

    def join(self, timeout: float = 5.0) -> None:
        self._thread.join(timeout)


class Replay:
    def __init__(self, plan: Plan, log: Callable[[str], None] = print):
        self.plan = plan
        self.log = log
        self.written: list[Path] = []
        self.frames: list[Path] = []
        self.display: str | None = None
        self._work: tempfile.TemporaryDirectory | None = None

    # The whole replay: a private master, its processes, the outputs. Raises ReplayFailure.
    def run(self) -> list[Path]:
        from magna_common.ros_master import RosMaster, RosMasterError

        options = self.plan.options
        self._work = tempfile.TemporaryDirectory(prefix="magna_replay_")
        work = Path(self._work.name)
        previous = _terminate_as_interrupt()
        try:
            with RosMaster(log_dir=work / "ros_log") as master:
                self._set_param(master, "/use_sim_time", True)
                env = self._display_env(master, work)
                config_path = rc.write_config(
                    rc.adapt(self.plan.config, view=self.plan.view, grid_box=self.plan.box,
                             headless=options.size if options.headless else None),
                    work / f"replay_{self.plan.choice.path.stem}.rviz")
                scene = self._spawn_logged(master, self._scene_argv(), work, "scene", env=env)
                rviz_argv = ["rviz", "-d", str(config_path)] + (["--fullscreen"] if options.headless else [])
                rviz = self._spawn_logged(master, rviz_argv, work, "rviz", env=env, cwd=work)
                self._wait_ready(master, {"scene node": (scene, work / "scene.log"),
                                          "rviz": (rviz, work / "rviz.log")})
                if options.headless:
                    self._prepare_out_dir()
                play = master.spawn(self._play_argv(), env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL)
                progress = _Progress(play.stdout)
                if options.headless:
                    self._headless(play, progress, rviz, work)
                else:
                    self._interactive(play, progress, rviz)
        except RosMasterError as err:
            raise ReplayFailure(f"the private ROS master did not start: {err}") from None
        finally:
            signal.signal(signal.SIGTERM, previous)
            self._work.cleanup()
        return self.written

    def _set_param(self, master, name: str, value) -> None:
        xmlrpc.client.ServerProxy(master.uri).setParam("/magna_replay", name, value)

    def _spawn_logged(self, master, argv: list[str], work: Path, name: str, **kwargs):
        """A process of the master with its output in work/<name>.log."""
        with open(work / f"{name}.log", "wb") as log:
            return master.spawn(argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, **kwargs)

    def _display_env(self, master, work: Path) -> dict:
        env = dict(os.environ)
        runtime = work / "xdg"
        runtime.mkdir(mode=0o700)
        env["XDG_RUNTIME_DIR"] = str(runtime)
        if self.plan.options.headless:
            self.display = self._start_xvfb(master, work)
            env["DISPLAY"] = self.display
            # rviz keeps its settings in $HOME/.rviz: a headless replay leaves the user's untouched
            env["HOME"] = str(work / "home")
            (work / "home").mkdir()
        return env

    def _start_xvfb(self, master, work: Path) -> str:
        width, height = self.plan.options.size
        read_end, write_end = os.pipe()
        try:
            xvfb = self._spawn_logged(master, ["Xvfb", "-displayfd", str(write_end), "-screen", "0",
                                               f"{width}x{height}x24", "+extension", "GLX", "-nolisten", "tcp",
                                               "-noreset"], work, "xvfb", pass_fds=(write_end,))
            os.close(write_end)
            write_end = -1
            number = b""
            deadline = time.monotonic() + 30.0
            while not number.endswith(b"\n"):
                left = deadline - time.monotonic()
                ready, _, _ = select.select([read_end], [], [], max(left, 0))
                if not ready:
                    raise ReplayFailure("Xvfb did not start within 30 s" + _tail(work / "xvfb.log"))
                chunk = os.read(read_end, 16)
                if not chunk:
                    raise ReplayFailure(f"Xvfb ended at start (exit {xvfb.poll()})" + _tail(work / "xvfb.log"))
                number += chunk
        finally:
            os.close(read_end)
            if write_end >= 0:
                os.close(write_end)
        return f":{int(number.strip())}"

    def _scene_argv(self) -> list[str]:
        return [sys.executable, str(NODES_DIR / "scene"), "__name:=magna_scene",
                f"_mission_file:={self.plan.mission_file}", f"_scale:={self.plan.scale:g}",
                f"_world_in:={VIZ_BAG_WORLD}", "_keep_world:=true", f"_topic:={VIZ_SCENE}"]

    def _play_argv(self) -> list[str]:
        options = self.plan.options
        return ["rosbag", "play", "--clock", "-d", "1", "-r", f"{options.speed:g}", *(["-l"] if options.loop else []),
                str(self.plan.bag.path), f"{WORLD_MARKERS}:={VIZ_BAG_WORLD}"]

    def _wait_ready(self, master, processes: dict) -> None:
        """Until rviz listens to the scene and the world, and the scene node to every UAV's pose."""
        wanted = {VIZ_SCENE: "rviz", WORLD_MARKERS: "rviz"}
        wanted.update({ual(i, "pose"): "scene node" for i in self.plan.uav_ids})
        proxy = xmlrpc.client.ServerProxy(master.uri)
        deadline = time.monotonic() + self.plan.options.start_timeout
        while True:
            for name, (process, log) in processes.items():
                if process.poll() is not None:
                    raise ReplayFailure(f"{name} ended at start (exit {process.returncode})" + _tail(log))
            answer: Any = proxy.getSystemState("/magna_replay")
            code, _msg, state = answer  # the ROS master API answers [code, status message, value]
            subscribed = {topic for topic, nodes in (state[1] if code == 1 else []) if nodes}
            waiting = [f"{who} on {topic}" for topic, who in wanted.items() if topic not in subscribed]
            if not waiting:
                return
            if time.monotonic() > deadline:
                raise ReplayFailure(f"not ready within {self.plan.options.start_timeout:g} s: waiting for "
                                    f"{', '.join(waiting)}" + _tail(processes["rviz"][1]))
            time.sleep(0.2)

    def _prepare_out_dir(self) -> None:
        out_dir = self.plan.out_dir
        assert out_dir is not None  # make_plan gives every headless replay its folder
        out_dir.mkdir(parents=True, exist_ok=True)
        if self.plan.options.force:  # numbered frames of an earlier replay would mix with these
            for old in out_dir.glob("frame_*.png"):
                old.unlink()

    # --- headless ------------------------------------------------------------------------------------------------

    def _grab(self):
        from PIL import ImageGrab

        return ImageGrab.grab(xdisplay=self.display).convert("RGB")

    def _save(self, image, path: Path) -> Path:
        return write_atomically(path, lambda out: image.save(out, format="PNG"), overwrite=True, binary=True)

    def _headless(self, play, progress: _Progress, rviz, work: Path) -> None:
        options, bag, out_dir = self.plan.options, self.plan.bag, self.plan.out_dir
        assert out_dir is not None  # make_plan gives every headless replay its folder
        bar = _bar(bag.duration, options.progress)
        next_shot = options.every if options.every > 0 else math.inf
        try:
            while play.poll() is None:
                if rviz.poll() is not None:
                    raise ReplayFailure(f"rviz ended during the replay (exit {rviz.returncode})"
                                        + _tail(work / "rviz.log"))
                elapsed = progress.elapsed
                if elapsed >= next_shot:
                    frame = out_dir / f"frame_{len(self.frames) + 1:04d}.png"
                    self.frames.append(self._save(self._grab(), frame))
                    while next_shot <= elapsed:
                        next_shot += options.every
                bar.update(min(elapsed, bag.duration) - bar.n)
                time.sleep(0.05)
            progress.join()
            if play.returncode != 0:
                said = progress.tail.decode(errors="replace").replace("\r", "\n").strip().splitlines()[-3:]
                raise ReplayFailure(f"rosbag play failed (exit {play.returncode})"
                                    + ("; its last output:\n  " + "\n  ".join(said) if said else ""))
            bar.update(bag.duration - bar.n)
        finally:
            bar.close()
        final = self._settled(rviz, work)
        self.written += self.frames
        self.written.append(self._save(final, out_dir / FINAL_NAME))
        images = self.frames + [out_dir / FINAL_NAME]
        if options.gif:
            self.written.append(write_gif(images, out_dir / GIF_NAME, options.fps))
        if options.mp4:
            self.written.append(write_mp4(images, out_dir / MP4_NAME, options.fps))

    def _settled(self, rviz, work: Path, least: float = 1.5, most: float = 15.0):
        """The screen once rviz has drawn the last state: two grabs half a second apart that agree."""
        time.sleep(least)
        deadline = time.monotonic() + most
        previous = self._grab()
        while time.monotonic() < deadline:
            if rviz.poll() is not None:
                raise ReplayFailure(f"rviz ended before the final frame (exit {rviz.returncode})"
                                    + _tail(work / "rviz.log"))
            time.sleep(0.5)
            current = self._grab()
            if current.tobytes() == previous.tobytes():
                return current
            previous = current
        return previous

    # --- on a display ------------------------------------------------------------------------------------------

    def _interactive(self, play, progress: _Progress, rviz) -> None:
        bar = _bar(self.plan.bag.duration, self.plan.options.progress)
        try:
            while play.poll() is None:
                if rviz.poll() is not None:
                    self.log("rviz was closed: the replay ends")
                    return
                if not self.plan.options.loop:
                    bar.update(min(progress.elapsed, self.plan.bag.duration) - bar.n)
                time.sleep(0.1)
        finally:
            bar.close()
        self.log("the bag has ended; rviz shows the last state: close rviz (or press Ctrl-C) to finish")
        try:
            while rviz.poll() is None:
                time.sleep(0.2)
        except KeyboardInterrupt:  # the usual way to finish here, not an interruption
            pass


def _bar(total: float, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, unit="s", desc="replay", disable=not enabled, file=sys.stderr,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} s of bag [{elapsed}<{remaining}]",
                mininterval=0.5)


def _tail(log: Path, lines: int = 6) -> str:
    try:
        text = log.read_text(errors="replace").strip().splitlines()
    except OSError:
        return ""
    text = [line for line in text if line.strip()][-lines:]
    return ("; its last output:\n  " + "\n  ".join(text)) if text else ""


def _terminate_as_interrupt():
    """SIGTERM ends a replay like Ctrl-C (its processes are ended); returns the previous handler."""
    def handler(_signum, _frame):
        raise KeyboardInterrupt

    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave it
        return signal.getsignal(signal.SIGTERM)

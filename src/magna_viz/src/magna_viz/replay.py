"""Replay a simulation's bag into rviz, on the user's display or headless under Xvfb with screenshots.

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
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import xmlrpc.client
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from magna_common.files import write_atomically
from magna_common.simulation_bag import BagError, read_simulation_bag
from magna_viz import rviz_config as rc

BAG_NAME = "simulation.bag"
OUT_DIR_NAME = "replay"
SCENE_TOPIC = "/magna/viz/scene"
BAG_WORLD_TOPIC = "/magna/viz/bag_world"  # the bag's /magna/world/markers, relayed by the scene node
WORLD_TOPIC = "/magna/world/markers"
NODES_DIR = Path(__file__).resolve().parents[2] / "nodes"
FLIGHT_KINDS = ("pose", "goal", "path/raw", "path/smoothed")  # where the UAVs flew and were sent
PROGRESS = re.compile(rb"Duration:\s*([0-9.]+)\s*/\s*([0-9.]+)")
FITS = ("world", "uavs", "none")
GIF_MAX_WIDTH = 800


class ReplayError(ValueError):
    """Bad input (missing bag, not a bag, outputs in the way, no display): nothing was started or written."""


class ReplayFailure(RuntimeError):
    """Something started failed (rviz, Xvfb, rosbag play): every process is ended, the message says where."""


@dataclass
class ReplayOptions:
    source: Path  # a bag, or a simulation folder holding simulation.bag
    headless: bool = False
    out_dir: Path | None = None  # headless outputs; default <simulation folder>/replay
    every: float = 1.0  # s of bag time between screenshots; 0: only the final frame
    speed: float = 1.0
    gif: bool = False
    mp4: bool = False
    fps: float = 5.0  # frames per second of the GIF and MP4
    force: bool = False
    config: Path | None = None
    mission_file: Path | None = None
    size: tuple[int, int] = (1280, 720)
    fit: str = "world"
    loop: bool = False
    progress: bool = True
    start_timeout: float = 120.0  # wall s for Xvfb, rviz and the scene node to come up


@dataclass
class BagSummary:
    path: Path
    start: float
    end: float
    messages: int
    uav_ids: list[int]
    flight_box: rc.Box | None

    @property
    def duration(self) -> float:
        return max(self.end - self.start, 0.0)


@dataclass
class Plan:
    """Everything checked before anything starts."""

    options: ReplayOptions
    bag: BagSummary
    sim_dir: Path
    mission_file: Path
    choice: rc.ConfigChoice
    config: dict
    view: rc.OrbitView | None
    box: rc.Box | None
    scale: float
    out_dir: Path | None
    uav_ids: list[int] = field(default_factory=list)  # the mission's agents: the scene node draws these
    notes: list[str] = field(default_factory=list)

    def outputs(self) -> list[Path]:
        """The files a headless replay writes (frames are numbered as they come)."""
        if self.out_dir is None:
            return []
        names = ["final.png"] + (["replay.gif"] if self.options.gif else []) + (["replay.mp4"] if self.options.mp4
                                                                               else [])
        return [self.out_dir / n for n in names]


# --- checking the input ------------------------------------------------------------------------------------------

def resolve_source(source: Path) -> tuple[Path, Path]:
    """(bag, simulation folder) of a bag file or a simulation folder."""
    source = Path(source).expanduser()
    if source.is_dir():
        bag = source / BAG_NAME
        if not bag.is_file():
            raise ReplayError(f"{source}: no {BAG_NAME} in this folder (was the simulation run with --no-bag?)")
        return bag.resolve(), source.resolve()
    if not source.exists():
        raise ReplayError(f"{source}: no such bag file or simulation folder")
    if not source.is_file():
        raise ReplayError(f"{source}: not a file or folder")
    return source.resolve(), source.resolve().parent


def read_bag(bag: Path) -> BagSummary:
    """Duration, UAVs and where they flew; ReplayError when the file is not a readable bag."""
    try:
        data = read_simulation_bag(bag, kinds=FLIGHT_KINDS)
    except BagError as err:
        raise ReplayError(str(err)) from None
    if data.message_count == 0:
        raise ReplayError(f"{bag}: the bag holds no messages; nothing to replay")
    points = []
    for message in (m for kind in FLIGHT_KINDS for m in data.of(kind)):
        if hasattr(message.msg, "poses"):  # a path
            points += [(s.pose.position.x, s.pose.position.y, s.pose.position.z) for s in message.msg.poses]
        else:
            p = message.msg.pose.position
            points.append((p.x, p.y, p.z))
    return BagSummary(bag, data.start / 1e9, data.end / 1e9, data.message_count, data.uav_ids("pose"),
                      rc.box_of_points(points))


def read_world(sim_dir: Path) -> dict | None:
    import json

    path = sim_dir / "world.json"
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def view_box(world: dict | None, flights: rc.Box | None, fit: str) -> rc.Box | None:
    """What the camera shows: the world's content inside its boundaries and the flights ('world'), or the
    flights only ('uavs'), padded; None for 'none' or when nothing is known."""
    if fit == "none":
        return None
    boundaries, content = rc.world_boxes(world) if world else (None, None)
    if fit == "uavs" and flights is not None:
        return rc.pad(flights, 0.15)
    inside = rc.clip(content, boundaries) if content is not None else None
    box = rc.union(inside, flights)
    if box is None:
        box = boundaries
    return rc.pad(box) if box is not None else None


def make_plan(options: ReplayOptions, environ: dict | None = None) -> Plan:
    """Check everything a replay needs; ReplayError (nothing started, nothing written) when something is off."""
    from magna_viz.scene import styles_from_mission

    environ = os.environ if environ is None else environ
    if not options.speed > 0 or not math.isfinite(options.speed):
        raise ReplayError(f"--speed must be > 0, got {options.speed:g}")
    if options.every < 0 or not math.isfinite(options.every):
        raise ReplayError(f"--every must be >= 0 seconds (0: only the final frame), got {options.every:g}")
    if not options.fps > 0:
        raise ReplayError(f"--fps must be > 0, got {options.fps:g}")
    if options.fit not in FITS:
        raise ReplayError(f"--fit must be one of {', '.join(FITS)}, got {options.fit!r}")
    width, height = options.size
    if not (160 <= width <= 7680 and 120 <= height <= 4320):
        raise ReplayError(f"--size {width}x{height}: give WIDTHxHEIGHT between 160x120 and 7680x4320")
    if options.headless and options.loop:
        raise ReplayError("--loop plays the bag forever: it needs a display, not --headless")

    bag_path, sim_dir = resolve_source(options.source)
    mission_file = Path(options.mission_file) if options.mission_file else sim_dir / "mission.json"
    if not mission_file.is_file():
        raise ReplayError(f"{mission_file}: no mission file (the UAVs' colours come from it); give one with "
                          "--mission FILE")
    try:
        styles = styles_from_mission(mission_file)
    except ValueError as err:
        raise ReplayError(str(err)) from None
    if not styles:
        raise ReplayError(f"{mission_file}: the mission has no agents to draw")
    if options.config is not None and not Path(options.config).is_file():
        raise ReplayError(f"--config {options.config}: no such file")

    tools = ["rosmaster", "rosbag", "rviz"] + (["Xvfb"] if options.headless else []) + (["ffmpeg"] if options.mp4
                                                                                           else [])
    import shutil

    missing = [t for t in tools if shutil.which(t) is None]
    if missing:
        raise ReplayError(f"{', '.join(missing)} not on PATH: run through ./magna, or install the Debian packages "
                          "of scripts/apt-packages.txt (make setup)")
    if not options.headless and not environ.get("DISPLAY"):
        raise ReplayError("no display (DISPLAY is not set) for rviz: use --headless to write screenshots instead")

    out_dir = None
    if options.headless:
        out_dir = Path(options.out_dir).expanduser() if options.out_dir else sim_dir / OUT_DIR_NAME
        if out_dir.exists() and not out_dir.is_dir():
            raise ReplayError(f"{out_dir}: exists and is not a folder; choose another with -o/--output")

    bag = read_bag(bag_path)
    world = rc.world_of_sim_dir(sim_dir)
    try:
        choice = rc.choose_config(world, Path(options.config) if options.config else None)
        config = rc.load_config(choice.path)
    except rc.ConfigError as err:
        raise ReplayError(str(err)) from None
    box = view_box(read_world(sim_dir), bag.flight_box, options.fit)
    view = None
    if box is not None:
        yaw, pitch = rc.view_of(config)
        aspect = width / height if options.headless else 1.2  # the 3-D view between rviz's docks
        view = rc.fit_orbit(box, yaw, pitch, aspect)
    plan = Plan(options, bag, sim_dir, mission_file, choice, config, view, box,
                rc.marker_scale_for(box, choice.family), out_dir, [s.id for s in styles])
    if choice.note:
        plan.notes.append(choice.note)
    missing_uavs = sorted(set(bag.uav_ids) - {s.id for s in styles})
    if missing_uavs:
        plan.notes.append(f"UAVs {', '.join(map(str, missing_uavs))} of the bag are not in {mission_file.name}: "
                          "not drawn")
    if out_dir is not None:
        in_the_way = [p for p in plan.outputs() if p.exists()]
        if options.every > 0 and out_dir.is_dir():
            in_the_way += sorted(out_dir.glob("frame_*.png"))[:1]
        if in_the_way and not options.force:
            raise ReplayError(f"{in_the_way[0]} exists; use --force to replace the replay's outputs in {out_dir} "
                              "(or -o/--output another folder)")
    return plan


# --- running ----------------------------------------------------------------------------------------------------

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
                f"_world_in:={BAG_WORLD_TOPIC}", "_keep_world:=true", f"_topic:={SCENE_TOPIC}"]

    def _play_argv(self) -> list[str]:
        options = self.plan.options
        return ["rosbag", "play", "--clock", "-d", "1", "-r", f"{options.speed:g}", *(["-l"] if options.loop else []),
                str(self.plan.bag.path), f"{WORLD_TOPIC}:={BAG_WORLD_TOPIC}"]

    def _wait_ready(self, master, processes: dict) -> None:
        """Until rviz listens to the scene and the world, and the scene node to every UAV's pose."""
        wanted = {SCENE_TOPIC: "rviz", WORLD_TOPIC: "rviz"}
        wanted.update({f"/uav_{i}/ual/pose": "scene node" for i in self.plan.uav_ids})
        proxy = xmlrpc.client.ServerProxy(master.uri)
        deadline = time.monotonic() + self.plan.options.start_timeout
        while True:
            for name, (process, log) in processes.items():
                if process.poll() is not None:
                    raise ReplayFailure(f"{name} ended at start (exit {process.returncode})" + _tail(log))
            code, _msg, state = proxy.getSystemState("/magna_replay")
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
        options, bag = self.plan.options, self.plan.bag
        bar = _bar(bag.duration, options.progress)
        next_shot = options.every if options.every > 0 else math.inf
        try:
            while play.poll() is None:
                if rviz.poll() is not None:
                    raise ReplayFailure(f"rviz ended during the replay (exit {rviz.returncode})"
                                        + _tail(work / "rviz.log"))
                elapsed = progress.elapsed
                if elapsed >= next_shot:
                    frame = self.plan.out_dir / f"frame_{len(self.frames) + 1:04d}.png"
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
        self.written.append(self._save(final, self.plan.out_dir / "final.png"))
        images = self.frames + [self.plan.out_dir / "final.png"]
        if options.gif:
            self.written.append(write_gif(images, self.plan.out_dir / "replay.gif", options.fps))
        if options.mp4:
            self.written.append(write_mp4(images, self.plan.out_dir / "replay.mp4", options.fps))

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


def write_gif(images: list[Path], path: Path, fps: float) -> Path:
    from PIL import Image

    frames = []
    for image in images:
        with Image.open(image) as im:
            im = im.convert("RGB")
            if im.width > GIF_MAX_WIDTH:
                im = im.resize((GIF_MAX_WIDTH, round(im.height * GIF_MAX_WIDTH / im.width)), Image.LANCZOS)
            frames.append(im.quantize(colors=255, method=Image.Quantize.MEDIANCUT))
    duration = max(int(round(1000.0 / fps)), 20)
    durations = [duration] * (len(frames) - 1) + [max(duration, 2000)]  # hold the final frame
    return write_atomically(path, lambda out: frames[0].save(out, format="GIF", save_all=True, append_images=frames[1:],
                                                             duration=durations, loop=0), overwrite=True, binary=True)


def write_mp4(images: list[Path], path: Path, fps: float) -> Path:
    """H.264 through Debian's ffmpeg, the PNGs piped in; the final frame is held for two seconds."""
    hold = max(int(round(2 * fps)), 1)
    sequence = images[:-1] + [images[-1]] * hold

    def encode(out) -> None:
        # ffmpeg must seek back to move the index to the front (+faststart), so it writes a file of its own,
        # beside the target, whose bytes then go into the atomic write.
        with tempfile.TemporaryDirectory(prefix=".mp4.", dir=path.parent) as work:
            encoded = Path(work) / path.name
            _ffmpeg(sequence, encoded, fps)
            with open(encoded, "rb") as source:
                shutil.copyfileobj(source, out)

    return write_atomically(path, encode, overwrite=True, binary=True)


def _ffmpeg(sequence: list[Path], target: Path, fps: float) -> None:
    argv = ["ffmpeg", "-y", "-loglevel", "error", "-f", "image2pipe", "-framerate", f"{fps:g}",
            "-c:v", "png", "-i", "-", "-c:v", "libx264", "-pix_fmt", "yuv420p",
            "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-movflags", "+faststart", "-f", "mp4", str(target)]
    with subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          start_new_session=True) as ffmpeg:
        try:
            for image in sequence:
                ffmpeg.stdin.write(image.read_bytes())
            ffmpeg.stdin.close()
        except BrokenPipeError:
            pass
        error = ffmpeg.stderr.read().decode(errors="replace").strip()
        if ffmpeg.wait() != 0:
            raise ReplayFailure(f"ffmpeg could not write {target.name}: {error or 'exit ' + str(ffmpeg.returncode)}")


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

"""A headless replay's media: its frames as a GIF (Pillow) and an MP4 (H.264 through ffmpeg)."""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import IO

from magna_common.files import write_atomically
from magna_viz.replay.errors import ReplayFailure

GIF_MAX_WIDTH = 800


def write_gif(images: list[Path], path: Path, fps: float) -> Path:
    from PIL import Image

    frames = []
    for image in images:
        with Image.open(image) as opened:
            im = opened.convert("RGB")
            if im.width > GIF_MAX_WIDTH:
                im = im.resize((GIF_MAX_WIDTH, round(im.height * GIF_MAX_WIDTH / im.width)),
                               Image.Resampling.LANCZOS)
            frames.append(im.quantize(colors=255, method=Image.Quantize.MEDIANCUT))
    duration = max(int(round(1000.0 / fps)), 20)
    durations = [duration] * (len(frames) - 1) + [max(duration, 2000)]  # hold the final frame
    return write_atomically(path, lambda out: frames[0].save(out, format="GIF", save_all=True, append_images=frames[1:],
                                                             duration=durations, loop=0), overwrite=True, binary=True)


def write_mp4(images: list[Path], path: Path, fps: float) -> Path:
    """H.264 through Debian's ffmpeg, the PNGs piped in; the final frame is held for two seconds."""
    hold = max(int(round(2 * fps)), 1)
    sequence = images[:-1] + [images[-1]] * hold

    def encode(out: IO[bytes]) -> None:
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
        stdin, stderr = ffmpeg.stdin, ffmpeg.stderr
        assert stdin is not None and stderr is not None  # both are pipes (PIPE above)
        try:
            for image in sequence:
                stdin.write(image.read_bytes())
            stdin.close()
        except BrokenPipeError:
            pass
        error = stderr.read().decode(errors="replace").strip()
        if ffmpeg.wait() != 0:
            raise ReplayFailure(f"ffmpeg could not write {target.name}: {error or 'exit ' + str(ffmpeg.returncode)}")

"""The recording chain: the camera's 8-bit views through an H.264 encode and decode, as the
recorder of real clips does (``camera_rig.recording``; off by default).

libx264 through PyAV (FFmpeg's own bindings), one encoder and one decoder per stream and sequence,
single-threaded (``threads=1``: same frames in => same bytes out) and with zero latency (no
B-frames, no look-ahead: every frame in gives its decoded frame back at once, so the stage runs
inside the camera model's frame loop). Grey frames go in as the luma plane with neutral chroma (no
range conversion of ours beyond ``video_range``); RGB frames through FFmpeg's swscale to 4:2:0 and
back (the chroma subsampling is part of what a recorder does). ``video_range: limited`` (default)
puts the 8-bit grey view on video levels, luma = 16 + 219 v / 255, and hands back the decoded luma
plane as it is: the benchmark's IR clips are such limited-range video (their luma spans 16-235).
Only the 8-bit views pass: radiometric counts and kelvin stay as the camera made them. Rate
control: constant rate factor ``crf`` or average ``bit_rate_bps``; a key frame every ``gop_frames``.
"""
from __future__ import annotations

from fractions import Fraction
from typing import Any

import numpy as np

from scenes.errors import UserInputError
from scenes.schema import Recording

ENCODER = "libx264"
DEFAULT_CRF = 28.0


def _open_encoder(width: int, height: int, frame_rate_hz: float, params: Recording, field: str):
    import av

    if ENCODER not in av.codecs_available:
        raise UserInputError(f"{field}: this PyAV build has no {ENCODER} encoder (the recording chain needs it)")
    ctx: Any = av.CodecContext.create(ENCODER, "w")   # a VideoCodecContext for a video encoder
    ctx.width, ctx.height, ctx.pix_fmt = width, height, "yuv420p"
    rate = Fraction(frame_rate_hz).limit_denominator(1001)
    ctx.framerate, ctx.time_base = rate, 1 / rate
    ctx.gop_size = params.gop_frames
    ctx.thread_count = 1
    options = {"preset": params.preset, "tune": "zerolatency", "threads": "1"}
    if params.bit_rate_bps is not None:
        ctx.bit_rate = int(params.bit_rate_bps)
    else:
        options["crf"] = repr(float(params.crf if params.crf is not None else DEFAULT_CRF))
    ctx.options = options
    try:
        ctx.open()
    except (av.error.FFmpegError, ValueError) as exc:
        what = (f"bit_rate_bps {params.bit_rate_bps}" if params.bit_rate_bps is not None
                else f"crf {params.crf}")
        raise UserInputError(f"{field}.{what.split()[0]} = {what.split()[1]}: {ENCODER} refuses it "
                             f"for {width}x{height} at {frame_rate_hz:g} Hz ({exc})") from None
    return ctx


class H264Stream:
    """One camera's 8-bit frames (H, W) grey or (H, W, 3) RGB through encode + decode, in frame order."""

    def __init__(self, width_px: int, height_px: int, frame_rate_hz: float, params: Recording, colour: bool,
                 field: str = "camera_rig.recording"):
        import av

        self.width, self.height, self.colour = width_px, height_px, colour
        self.coded_w, self.coded_h = width_px + width_px % 2, height_px + height_px % 2   # 4:2:0 needs even sizes
        self.encoder = _open_encoder(self.coded_w, self.coded_h, frame_rate_hz, params, field)
        self.decoder = av.CodecContext.create("h264", "r")
        self.decoder.thread_count = 1
        self.decoder.thread_type = "NONE"
        self.index = 0
        self.bytes_written = 0
        levels = np.arange(256, dtype=np.float64)
        self.luma_lut = (np.rint(16.0 + levels * 219.0 / 255.0) if params.video_range == "limited"
                         else levels).astype(np.uint8)

    def _pad(self, image: np.ndarray) -> np.ndarray:
        if (self.coded_h, self.coded_w) == image.shape[:2]:
            return np.ascontiguousarray(image)
        pad = ((0, self.coded_h - image.shape[0]), (0, self.coded_w - image.shape[1])) + ((0, 0),) * (image.ndim - 2)
        return np.pad(image, pad, mode="edge")

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """The decoded frame (fresh uint8 array, the input's shape)."""
        import av

        image = self._pad(np.asarray(image, dtype=np.uint8))
        if self.colour:
            frame = av.VideoFrame.from_ndarray(image, format="rgb24").reformat(format="yuv420p")
        else:
            chroma = np.full((self.coded_h // 2, self.coded_w), 128, np.uint8)
            luma = self.luma_lut.take(image)
            frame = av.VideoFrame.from_ndarray(np.concatenate([luma, chroma]), format="yuv420p")
        frame.pts = self.index
        decoded = []
        for packet in self.encoder.encode(frame):
            self.bytes_written += packet.size
            decoded.extend(self.decoder.decode(packet))
        if len(decoded) != 1:
            raise RuntimeError(f"H.264 stage: frame {self.index} gave {len(decoded)} decoded frames (expected 1: "
                               f"zero-latency encoding)")
        self.index += 1
        out = decoded[0]
        if self.colour:
            return out.to_ndarray(format="rgb24")[:self.height, :self.width].copy()
        return out.to_ndarray()[:self.height, :self.width].copy()      # the luma plane


class RecordingChain:
    """The H.264 stage for both cameras of a rig: ``rgb8`` and ``thermal_agc8`` of each frame."""

    def __init__(self, params: Recording, rgb_size: tuple[int, int], thermal_size: tuple[int, int],
                 frame_rate_hz: float):
        self.params = params
        self.rgb = H264Stream(*rgb_size, frame_rate_hz, params, colour=True)
        self.thermal = H264Stream(*thermal_size, frame_rate_hz, params, colour=False)

    def metadata(self) -> dict:
        import av

        return {**self.params.model_dump(mode="json"), "encoder": ENCODER, "tune": "zerolatency", "threads": 1,
                "pyav": av.__version__,
                "crf_used": None if self.params.bit_rate_bps is not None else
                float(self.params.crf if self.params.crf is not None else DEFAULT_CRF)}

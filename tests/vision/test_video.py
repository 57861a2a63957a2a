"""Video reading: frames, indices and rate of files written here and of the real Pose2Sim clips."""

import cv2
import numpy as np
import pytest

from jaxtrack.data import shared_folder
from jaxtrack.vision import VideoError, iter_video_chunks, read_video, to_grey

SHARED = shared_folder()
POSE2SIM = None if SHARED is None else SHARED / "pose2sim_demo_singleperson/videos/cam01.mp4"
WIDTH, HEIGHT, FRAMES, FPS = 96, 64, 12, 25.0


def frame(t: int) -> np.ndarray:
    """Frame t (RGB): a grey level that encodes t, with a coloured square in one corner."""
    image = np.full((HEIGHT, WIDTH, 3), 20 * t, np.uint8)
    image[:16, :16] = (230, 40, 40)  # red in RGB: checks the BGR → RGB swap
    return image


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    path = tmp_path_factory.mktemp("video") / "counting.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (WIDTH, HEIGHT))
    assert writer.isOpened()
    for t in range(FRAMES):
        writer.write(cv2.cvtColor(frame(t), cv2.COLOR_RGB2BGR))
    writer.release()
    return path


def frame_number(frames: np.ndarray) -> np.ndarray:
    """Recover t from the decoded grey level of each frame (mp4v is lossy, so round)."""
    height, width = frames.shape[1:3]
    return np.round(frames[:, height // 2:, width // 2:].mean(axis=(1, 2, 3)) / 20).astype(int)


def test_read_back_a_written_video(clip):
    video = read_video(clip)
    assert video.frames.shape == (FRAMES, HEIGHT, WIDTH, 3) and video.frames.dtype == np.uint8
    assert video.fps == pytest.approx(FPS) and video.source_fps == pytest.approx(FPS)
    assert video.path == clip and video.image_size == (WIDTH, HEIGHT)
    np.testing.assert_array_equal(video.frame_indices, np.arange(FRAMES))
    np.testing.assert_array_equal(frame_number(video.frames), np.arange(FRAMES))
    corner = video.frames[:, 4:12, 4:12].mean(axis=(0, 1, 2))
    assert corner[0] > 180 and corner[2] < 90  # red stays red: RGB, not OpenCV's BGR


def test_start_stride_max_frames_and_scale(clip):
    video = read_video(clip, start=2, stride=3, max_frames=3, scale=0.5)
    np.testing.assert_array_equal(video.frame_indices, [2, 5, 8])
    np.testing.assert_array_equal(frame_number(video.frames), [2, 5, 8])
    assert video.frames.shape == (3, HEIGHT // 2, WIDTH // 2, 3)
    assert video.fps == pytest.approx(FPS / 3)  # the returned frames are 3 file frames apart
    np.testing.assert_allclose(video.times, np.array([2, 5, 8]) / FPS)
    tail = read_video(clip, start=FRAMES - 2, stride=5)
    np.testing.assert_array_equal(tail.frame_indices, [FRAMES - 2])


def test_chunks_concatenate_to_the_whole(clip):
    whole = read_video(clip, start=1, stride=2)
    chunks = list(iter_video_chunks(clip, 2, start=1, stride=2))
    assert [chunk.num_frames for chunk in chunks] == [2, 2, 2]
    np.testing.assert_array_equal(np.concatenate([c.frames for c in chunks]), whole.frames)
    np.testing.assert_array_equal(np.concatenate([c.frame_indices for c in chunks]),
                                  whole.frame_indices)
    uneven = list(iter_video_chunks(clip, 5))
    assert [chunk.num_frames for chunk in uneven] == [5, 5, 2]


def test_grey_chunks_equal_to_grey_of_the_rgb_frames_bit_for_bit(clip):
    """The grey path skips the RGB copy but computes the same float32 sums in the same order;
    a first chunk of its own size lines up with a tracker's set-up frame."""
    whole = read_video(clip, start=1, scale=0.5)
    chunks = list(iter_video_chunks(clip, 4, start=1, scale=0.5, grey=True,
                                    first_chunk_size=5))
    assert [chunk.num_frames for chunk in chunks] == [5, 4, 2]
    grey = np.concatenate([chunk.frames for chunk in chunks])
    assert grey.dtype == np.float32 and grey.shape == whole.frames.shape[:3]
    np.testing.assert_array_equal(grey, to_grey(whole.frames))  # swapped weights would fail
    np.testing.assert_array_equal(np.concatenate([c.frame_indices for c in chunks]),
                                  whole.frame_indices)
    colour = list(iter_video_chunks(clip, 4, first_chunk_size=5))
    assert [chunk.num_frames for chunk in colour] == [5, 4, 3]
    with pytest.raises(ValueError, match="first_chunk_size must be ≥ 1"):
        iter_video_chunks(clip, 4, first_chunk_size=0)


def test_missing_corrupt_and_non_video_files_raise_naming_the_file(tmp_path, clip):
    missing = tmp_path / "nowhere.mp4"
    with pytest.raises(VideoError, match="nowhere.mp4: no such video file"):
        read_video(missing)
    with pytest.raises(VideoError, match="nowhere.mp4"):
        iter_video_chunks(missing, 4)  # raises at the call, not at the first next()
    noise = tmp_path / "noise.mp4"
    noise.write_bytes(np.random.default_rng(0).bytes(20_000))
    text = tmp_path / "notes.avi"
    text.write_text("this is not a video\n" * 100)
    truncated = tmp_path / "truncated.mp4"
    truncated.write_bytes(clip.read_bytes()[: clip.stat().st_size // 2])
    for path in (noise, text, truncated):
        with pytest.raises(VideoError, match=path.name):
            read_video(path)
    with pytest.raises(VideoError, match="directory|not a file"):
        read_video(tmp_path)


def test_video_without_frames_raises(tmp_path, clip):
    empty = tmp_path / "empty.mp4"
    writer = cv2.VideoWriter(str(empty), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (WIDTH, HEIGHT))
    writer.release()
    with pytest.raises(VideoError, match="empty.mp4"):
        read_video(empty)
    with pytest.raises(VideoError, match=f"has {FRAMES} frames, none at or after start=40"):
        read_video(clip, start=40)
    with pytest.raises(VideoError, match="start=40"):
        next(iter_video_chunks(clip, 4, start=40))


def test_bad_options_raise():
    for options in ({"stride": 0}, {"max_frames": 0}, {"start": -1}, {"scale": 0.0}):
        with pytest.raises(ValueError):
            read_video("unused.mp4", **options)
    with pytest.raises(ValueError, match="chunk_size"):
        iter_video_chunks("unused.mp4", 0)


def test_to_grey_matches_opencv():
    images = np.random.default_rng(0).integers(0, 256, (2, 7, 9, 3), dtype=np.uint8)
    grey = to_grey(images)
    assert grey.shape == (2, 7, 9) and grey.dtype == np.float32
    expected = np.stack([cv2.cvtColor(image, cv2.COLOR_RGB2GRAY) for image in images]) / 255
    np.testing.assert_allclose(grey, expected, atol=0.5 / 255 + 1e-6)  # OpenCV rounds to uint8
    np.testing.assert_allclose(to_grey(images / 255.0), grey, atol=1e-6)
    assert to_grey(np.full((3, 3, 3), 255, np.uint8)).max() == pytest.approx(1.0)
    with pytest.raises(ValueError, match="RGB"):
        to_grey(np.zeros((4, 4)))


@pytest.mark.skipif(POSE2SIM is None or not POSE2SIM.is_file(),
                    reason="the shared/data collection is not beside this checkout")
def test_real_pose2sim_video():
    video = read_video(POSE2SIM, max_frames=8, stride=4, scale=0.25)
    assert video.frames.shape == (8, 480, 270, 3)
    assert video.source_fps == pytest.approx(60.0) and video.fps == pytest.approx(15.0)
    np.testing.assert_array_equal(video.frame_indices, np.arange(0, 32, 4))
    assert 40 < video.frames.mean() < 220 and video.frames.std() > 20  # a real scene
    chunks = list(iter_video_chunks(POSE2SIM, 40, scale=0.125))
    assert [chunk.num_frames for chunk in chunks] == [40, 40, 20]  # all 100 frames


def test_opencv_and_ffmpeg_log_lines_are_kept_off_stderr(tmp_path):
    """A damaged video and a refused writer raise errors that name the file; FFmpeg's ``moov atom
    not found`` and OpenCV's ``[ERROR:0@...]`` lines used to be printed before them. FFmpeg
    reads its log level once per process, so this runs in a fresh one."""
    import subprocess
    import sys

    corrupt = tmp_path / "corrupt.mp4"
    corrupt.write_bytes(b"not a video" * 100)
    script = (
        "import sys\n"
        "import numpy as np\n"
        "from jaxtrack.vision import VideoError, read_video, write_frames\n"
        "try:\n"
        f"    read_video({str(corrupt)!r})\n"
        "except VideoError as error:\n"
        "    print('read:', error)\n"
        "try:\n"
        f"    write_frames([np.zeros((32, 32, 3), np.uint8)], {str(tmp_path / 'out.mp4')!r},"
        " 0.001, (32, 32))\n"
        "except OSError as error:\n"
        "    print('write:', error)\n")
    environment = {key: value for key, value in __import__("os").environ.items()
                   if not key.startswith(("OPENCV_LOG_LEVEL", "OPENCV_FFMPEG_LOGLEVEL"))}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=environment, timeout=120)
    assert "read: " in done.stdout and "corrupt.mp4" in done.stdout
    assert "write: " in done.stdout and "out.mp4" in done.stdout
    assert done.stderr == "", done.stderr
    assert not (tmp_path / "out.mp4").exists()

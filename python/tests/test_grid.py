"""chronomap.Grid against `chronomap grid build | predict | stats` on bundled real data: the
CASAS Aruba presence series (10 areas, one frame a minute for 16 weeks) and the ATC map."""

from __future__ import annotations

import lzma
import struct
import zlib

import numpy as np
import pytest

import chronomap._native as native
from chronomap.grid import Grid, load_grid, read_map

ARUBA = [f"data/aruba_rooms_1min/presence_minutes_{r}.txt.xz" for r in range(10)]
# Tuesday 2011-02-22 (the week after the data) at 03:00, 08:00, 14:00 and 21:00 UTC.
TIMES = [1298343600.0, 1298361600.0, 1298383200.0, 1298408400.0]


# ---------------------------------------------------------------------------------------------
# Reading what the command line writes


def read_pgm(path):
    """A binary PGM (P5) as an array, image rows top first."""
    data = path.read_bytes()
    fields = []
    pos = 0
    while len(fields) < 4:
        while data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            pos = data.index(b"\n", pos)
            continue
        end = pos
        while not data[end : end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    assert fields[0] == b"P5" and fields[3] == b"255"
    width, height = int(fields[1]), int(fields[2])
    return np.frombuffer(data[pos + 1 :], np.uint8).reshape(height, width)


def read_grey_alpha_png(path):
    """An 8-bit grey + alpha PNG (what `grid predict --mode scale` writes) as (H, W, 2)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat = 8, b""
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert (depth, color, interlace) == (8, 4, 0)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    bpp, stride = 2, 2 * width
    out = np.zeros((height, stride), np.int64)
    prev = np.zeros(stride, np.int64)
    for y in range(height):
        line = raw[y * (stride + 1) : (y + 1) * (stride + 1)]
        filt, row = line[0], np.frombuffer(line[1:], np.uint8).astype(np.int64)
        cur = np.zeros(stride, np.int64)
        for x in range(stride):
            a = cur[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if filt == 0:
                pred = 0
            elif filt == 1:
                pred = a
            elif filt == 2:
                pred = b
            elif filt == 3:
                pred = (a + b) // 2
            else:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (row[x] + pred) & 0xFF
        out[y], prev = cur, cur
    return out.reshape(height, width, 2)


def percent(p):
    """`chronomap grid predict`'s cell values: round(100 p), -1 for NaN."""
    v = np.floor(100.0 * np.clip(p.astype(np.float64), 0, 1) + 0.5)  # ties away from zero
    return np.where(np.isnan(p), -1, v).astype(np.int64)


def trinary(p):
    """The trinary PGM pixels of a predicted map (map_saver: free <= 20 %, occupied >= 65 %),
    image rows top first."""
    v = percent(p)
    pixels = np.where(v < 0, 205, np.where(v <= 20, 254, np.where(v >= 65, 0, 205)))
    return np.flipud(pixels)


def scale_grey(p):
    """The grey levels of `--mode scale` (GraphicsMagick quanta), image rows top first."""
    v = percent(p)
    grey = np.array([int(int((100.0 - k) / 100.0 * 65535.0) / 257) for k in range(101)])
    return np.flipud(np.where(v < 0, int(int(0.5 * 65535.0) / 257), grey[np.clip(v, 0, 100)]))


# ---------------------------------------------------------------------------------------------
# Aruba: 10 cells, 161,280 frames


@pytest.fixture(scope="module")
def aruba(repo):
    """The frames of the Aruba areas as a (T, 1, 10) int8 array and their times."""
    series = [native.read_pairs(repo / f) for f in ARUBA]
    times = series[0][0]
    for t, _ in series[1:]:
        assert np.array_equal(t, times)
    frames = np.stack([np.round(100 * v) for _, v in series], axis=-1).astype(np.int8)
    return frames[:, None, :], times


@pytest.fixture(scope="module")
def aruba_cli_grid(repo, cli, tmp_path_factory):
    path = tmp_path_factory.mktemp("aruba") / "cli.cmg"
    cli("grid", "build", "--cell-series", ",".join(str(repo / f) for f in ARUBA), "-o", path)
    return path


def test_a_grid_from_frames_is_the_grid_the_cli_builds(aruba, aruba_cli_grid, tmp_path):
    frames, times = aruba
    grid = Grid.from_frames(frames, times, resolution=1.0, origin=(0.0, 0.0))
    assert grid.shape == (1, 10) and grid.frames == 161_280 and grid.kind == "grid-state"
    assert grid.span == (times[0], times[-1]) and grid.order == 2
    mine = tmp_path / "python.cmg"
    grid.save(mine)
    # Same frames, same configuration: the very same file, byte for byte.
    assert mine.read_bytes() == aruba_cli_grid.read_bytes()
    theirs = load_grid(aruba_cli_grid)
    for t in TIMES:
        p = grid.predict_map(t)
        assert p.shape == (1, 10) and p.dtype == np.float32
        np.testing.assert_array_equal(p, theirs.predict_map(t))
        for order in (0, 1, 4):
            np.testing.assert_array_equal(grid.predict_map(t, order=order),
                                          theirs.predict_map(t, order=order))


def test_predict_map_is_what_grid_predict_writes(aruba, aruba_cli_grid, cli, tmp_path):
    frames, times = aruba
    grid = Grid.from_frames(frames, times)
    mine = tmp_path / "python.cmg"
    grid.save(mine)
    seen = set()
    for t in TIMES:
        p = grid.predict_map(t)
        # The CLI predicts from the file Python wrote, and from its own.
        for source in (mine, aruba_cli_grid):
            out = tmp_path / f"map-{int(t)}-{source.stem}"
            report = cli("grid", "predict", source, "--time", t, "-o", out, "--mode", "scale",
                         json_output=True)
            assert (report["width"], report["height"]) == (10, 1)
            image = read_grey_alpha_png(out.with_suffix(".png"))
            np.testing.assert_array_equal(image[..., 0], scale_grey(p))
            assert (image[..., 1] == 255).all()
        seen.update(percent(p).ravel().tolist())
    # The comparison covers many distinct levels, not only empty rooms.
    assert len(seen) > 10, seen


def test_the_cli_reads_a_grid_saved_in_python(aruba, cli, tmp_path):
    frames, times = aruba
    grid = Grid.from_frames(frames[:20_160], times[:20_160], resolution=0.5, origin=(2.0, -1.5),
                            order=3)
    for store in ("state", "lossy"):
        path = tmp_path / f"{store}.cmg"
        grid.save(path, store=store)
        stats = cli("grid", "stats", path, json_output=True)
        assert stats["kind"] == f"grid-{store}"
        assert stats["geometry"]["width"] == 10 and stats["geometry"]["height"] == 1
        assert stats["geometry"]["resolution"] == 0.5
        assert stats["geometry"]["origin"] == [2.0, -1.5, 0.0]
        assert stats["frames"]["count"] == 20_160
        assert stats["frames"]["first"] == times[0] and stats["frames"]["last"] == times[20_159]
        again = load_grid(path)
        assert again.kind == f"grid-{store}" and again.origin == (2.0, -1.5)
        np.testing.assert_array_equal(again.predict_map(TIMES[1]), grid.predict_map(TIMES[1]))
    assert load_grid(tmp_path / "state.cmg").order == 3
    lossy = load_grid(tmp_path / "lossy.cmg")
    np.testing.assert_array_equal(grid.compact().predict_map(TIMES[2]), lossy.predict_map(TIMES[2]))
    with pytest.raises(ValueError, match="order: needs a learning-state grid"):
        lossy.predict_map(TIMES[2], order=1)


# ---------------------------------------------------------------------------------------------
# The ATC map as Nav2 frames


def write_trinary_map(base, data, resolution, origin):
    """A map_server map (YAML + trinary PGM) of int8 `data` (row 0 at the bottom)."""
    pixels = np.where(data < 0, 205, np.where(data >= 65, 0, 254)).astype(np.uint8)
    height, width = data.shape
    base.with_suffix(".pgm").write_bytes(
        b"P5\n%d %d\n255\n" % (width, height) + np.flipud(pixels).tobytes()
    )
    base.with_suffix(".yaml").write_text(
        f"image: {base.name}.pgm\nmode: trinary\nresolution: {resolution}\n"
        f"origin: [{origin[0]}, {origin[1]}, 0]\nnegate: 0\noccupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
    )


@pytest.fixture(scope="module")
def atc_frames(repo, tmp_path_factory):
    """Eight frames of the real ATC map, two days every six hours, in which a block of the
    corridor is blocked (occupied) at night and a strip is not seen (unknown) at noon."""
    data, resolution, origin = read_map(repo / "data/atc_copa_map_grid/atc_map.yaml")
    folder = tmp_path_factory.mktemp("atc")
    (folder / "maps").mkdir()
    lines, frames, times = ["# t map"], [], []
    for k in range(8):
        t = 1351036800.0 + 6 * 3600.0 * k
        frame = data.copy()
        if k % 4 == 0:  # midnight
            frame[160:200, 1840:1920] = 100
        if k % 4 == 2:  # noon
            frame[500:520, :] = -1
        write_trinary_map(folder / f"maps/frame_{k}", frame, 0.05, origin)
        lines.append(f"{t:.0f} maps/frame_{k}.yaml")
        frames.append(frame)
        times.append(t)
    (folder / "frames.txt").write_text("\n".join(lines) + "\n")
    return folder / "frames.txt", np.stack(frames), np.array(times), resolution, origin


def test_nav2_frames_give_the_grid_the_cli_builds(atc_frames, cli, tmp_path):
    frame_list, frames, times, resolution, origin = atc_frames
    grid = Grid.from_nav2(frame_list)
    assert grid.shape == (1200, 2800) and grid.frames == 8
    assert grid.resolution == resolution and grid.origin == (-60.0, -40.0)
    cli_file = tmp_path / "cli.cmg"
    cli("grid", "build", "--frames", frame_list, "-o", cli_file)
    mine = tmp_path / "python.cmg"
    grid.save(mine)
    assert mine.read_bytes() == cli_file.read_bytes()
    # The same frames as arrays (read back through read_map) make the same grid.
    again = Grid.from_frames(frames, times, resolution=resolution, origin=origin[:2])
    for t in (1351036800.0 + 86400 * 7, 1351036800.0 + 86400 * 7 + 12 * 3600):
        p = grid.predict_map(t)
        np.testing.assert_array_equal(p, again.predict_map(t))
        out = tmp_path / f"predicted-{int(t)}"
        report = cli("grid", "predict", mine, "--time", t, "-o", f"{out}.yaml", json_output=True)
        pgm = read_pgm(out.with_suffix(".pgm"))
        np.testing.assert_array_equal(pgm, trinary(p))
        assert report["occupied"] == int((percent(p) >= 65).sum())
        assert report["unknown"] == int((percent(p) < 0).sum())
    # The blocked block is predicted occupied at midnight and free at six in the morning.
    night = grid.predict_map(1351036800.0 + 86400 * 7)[160:200, 1840:1920]
    morning = grid.predict_map(1351036800.0 + 86400 * 7 + 6 * 3600)[160:200, 1840:1920]
    assert night.min() > 0.5 > morning.max()


# ---------------------------------------------------------------------------------------------
# Bad input


def test_frames_must_be_int8_occupancies_of_shape_t_h_w():
    times = [0.0, 60.0]
    good = np.zeros((2, 3, 4), np.int8)
    with pytest.raises(TypeError, match=r"frames: expected integer occupancies \(int8: -1 unknown, 0..100\), got dtype float64"):
        Grid.from_frames(good.astype(np.float64), times)
    with pytest.raises(TypeError, match="frames: expected integer occupancies .* got dtype <U10"):
        Grid.from_frames("not frames", times)
    with pytest.raises(ValueError, match=r"frames: expected a 3-D array \(T, H, W\) of occupancies, got shape \(3, 4\)"):
        Grid.from_frames(good[0], [0.0])
    with pytest.raises(ValueError, match=r"frames has 2 frames \(shape \(2, 3, 4\)\) but times has 3 values"):
        Grid.from_frames(good, [0.0, 1.0, 2.0])
    # Other integer dtypes are converted when every value fits, else the first misfit is named.
    wide = good.astype(np.int64)
    np.testing.assert_array_equal(Grid.from_frames(wide, times).predict_map(0.0),
                                  Grid.from_frames(good, times).predict_map(0.0))
    wide[1, 2, 3] = 300
    with pytest.raises(ValueError, match=r"frames\[1, 2, 3\]: occupancy 300 is not -1 \(unknown\) or 0..=100"):
        Grid.from_frames(wide, times)
    bad = good.copy()
    bad[1, 0, 2] = 101
    with pytest.raises(ValueError, match=r"frames\[1, 0, 2\]: occupancy 101 is not -1 \(unknown\) or 0..=100"):
        Grid.from_frames(bad, times)
    with pytest.raises(ValueError, match=r"frames\[0\]: every cell is unknown"):
        Grid.from_frames(np.full((2, 3, 4), -1, np.int8), times)
    with pytest.raises(ValueError, match="invalid grid geometry: resolution -1 is not a positive number"):
        Grid.from_frames(good, times, resolution=-1.0)
    with pytest.raises(ValueError, match="periods: "):
        Grid.from_frames(good, times, periods="fortnightly")


@pytest.mark.parametrize(
    ("times", "message"),
    [
        ([0.0, float("nan"), 2.0], r"frame 2 \(times\[1\]\): time NaN is not a finite number"),
        ([0.0, 1.0, float("inf")], r"frame 3 \(times\[2\]\): time inf is not a finite number"),
        ([0.0, 5.0, 4.0], r"frame 3 \(times\[2\]\): time 4 is earlier than the previous observation at 5"),
        ([-1.0, 5.0, 6.0], r"frame 1 \(times\[0\]\): time -1 is negative"),
    ],
)
def test_bad_times_are_named(times, message):
    with pytest.raises(ValueError, match=message):
        Grid.from_frames(np.zeros((3, 2, 2), np.int8), times)


def test_a_rejected_batch_leaves_the_grid_as_it_was():
    grid = Grid.from_frames(np.zeros((2, 2, 2), np.int8), [0.0, 60.0])
    before = grid.predict_map(100.0)
    frames = np.full((2, 2, 2), 100, np.int8)
    with pytest.raises(ValueError, match=r"frame 2 \(times\[1\]\): time 30 is earlier"):
        grid.observe(frames, [120.0, 30.0])
    assert grid.frames == 2
    np.testing.assert_array_equal(grid.predict_map(100.0), before)
    with pytest.raises(ValueError, match=r"expected frames of shape \(T, 2, 2\) for this grid, got shape \(1, 3, 2\)"):
        grid.observe(np.zeros((1, 3, 2), np.int8), [200.0])
    assert grid.observe(frames, [120.0, 180.0]) is grid and grid.frames == 4
    with pytest.raises(ValueError, match="time: nan is not a finite number|time: NaN is not a finite number"):
        grid.predict_map(float("nan"))


def test_nav2_frames_kept_with_history_give_the_lossless_file_the_cli_writes(atc_frames, cli, tmp_path):
    # Grid.from_nav2 runs the CLI's build job (chronomap-app); with keep_history=True the grid
    # can be stored lossless, byte for byte as `grid build --store lossless` stores it.
    frame_list = atc_frames[0]
    grid = Grid.from_nav2(frame_list, keep_history=True)
    mine = tmp_path / "python-lossless.cmg"
    grid.save(mine, store="lossless")
    cli_file = tmp_path / "cli-lossless.cmg"
    cli("grid", "build", "--frames", frame_list, "--store", "lossless", "-o", cli_file)
    assert mine.read_bytes() == cli_file.read_bytes()
    with pytest.raises(ValueError, match=r"store='lossless': .*keep_history=True"):
        Grid.from_nav2(frame_list).save(tmp_path / "refused.cmg", store="lossless")


def test_missing_and_damaged_files(tmp_path, atc_frames):
    missing = tmp_path / "nothing.cmg"
    with pytest.raises(FileNotFoundError, match="nothing.cmg"):
        load_grid(missing)
    with pytest.raises(FileNotFoundError, match="no-frames.txt"):
        Grid.from_nav2(tmp_path / "no-frames.txt")
    with pytest.raises(FileNotFoundError, match="atc_nowhere.yaml"):
        read_map(tmp_path / "atc_nowhere.yaml")
    listing = tmp_path / "frames.txt"
    listing.write_text("100 maps/gone.yaml\n")
    with pytest.raises(FileNotFoundError, match=r"frames.txt:1: .*gone.yaml"):
        Grid.from_nav2(listing)
    listing.write_text("100 a.yaml\nsoon b.yaml\n")
    with pytest.raises(ValueError, match=r'frames.txt:2: time: "soon" is not a number'):
        Grid.from_nav2(listing)

    grid = Grid.from_frames(np.zeros((2, 2, 2), np.int8), [0.0, 60.0])
    path = tmp_path / "grid.cmg"
    grid.save(path)
    data = bytearray(path.read_bytes())
    data[-3] ^= 0xFF
    damaged = tmp_path / "damaged.cmg"
    damaged.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="damaged.cmg"):
        load_grid(damaged)
    truncated = tmp_path / "truncated.cmg"
    truncated.write_bytes(bytes(data[: len(data) // 2]))
    with pytest.raises(ValueError, match="truncated.cmg"):
        load_grid(truncated)
    with pytest.raises(ValueError, match="store: \"dense\" is not one of 'state', 'lossy', 'lossless'"):
        grid.save(tmp_path / "x.cmg", store="dense")
    with pytest.raises(ValueError, match=r"store='lossless': .*keep_history=True"):
        grid.save(tmp_path / "x.cmg", store="lossless")
    kept = Grid.from_frames(np.zeros((2, 2, 2), np.int8), [0.0, 60.0], keep_history=True)
    kept.save(tmp_path / "lossless.cmg", store="lossless")
    assert load_grid(tmp_path / "lossless.cmg").kind == "grid-lossless"

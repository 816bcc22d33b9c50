"""Trial 26: 12-bit frames in 16-bit PNGs, frames unlike the model's, the annotations CSV as
spreadsheets export it, too small training frames named."""

import cv2
import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.io.media import frame_depth, read_frame
from artmotion.tracking.instruments.annotations import read_predictions, read_tools_csv
from artmotion.tracking.instruments.detector import ToolDetector

pytest.importorskip("torch")

ROWS = "1175,0,122,245,67.5,5.85\n1176,0,119,243,66.2,5.87\n"


class _Seeing:
    """A stand-in for a loaded model: one head on every frame; keeps each frame's brightest value."""
    threshold, max_heads_, frame_shape_, grey_ = 0.05, 4, (48, 64), False
    seen: list = []

    def detect(self, frame):
        self.seen.append(int(frame.max()))
        return np.array([[30.0, 20.0, 10.0, 0.5, 0.9]])


def _frames(folder, values, size=(48, 64), grey=False, dtype=np.uint8):
    """Frames of noise up to ``values[k]`` (of their ``dtype``)."""
    folder.mkdir()
    rng = np.random.default_rng(0)
    for k, top in enumerate(values, start=1):
        img = rng.integers(0, top + 1, (*size, 1 if grey else 3)).astype(dtype)
        cv2.imwrite(str(folder / f"{k:06d}.png"), np.repeat(img, 3, axis=2) if grey else img)
    return folder


@pytest.fixture
def stub(tmp_path, monkeypatch):
    _Seeing.seen = []
    monkeypatch.setattr(ToolDetector, "load", classmethod(lambda cls, path: _Seeing()))
    model = tmp_path / "m.pt"
    model.write_bytes(b"model")
    return model


def test_12_bit_frames_in_16_bit_pngs_are_scaled_by_their_depth(tmp_path, run_cli, stub):
    """0-4095 read by their top 8 bits were 0-15: nearly black, nothing found, no word."""
    frames = _frames(tmp_path / "f12", [4000, 4095, 3000], dtype=np.uint16)
    assert frame_depth(sorted(frames.iterdir())) == (12, 4095)
    img = read_frame(frames / "000002.png", 12)
    assert img.dtype == np.uint8 and img.max() == 255
    code, out, err = run_cli("tool", "track", frames, "--model", stub, "--out", tmp_path / "p.csv")
    assert code == 0, err
    assert "16-bit frames with values up to 4095 (in 5 spread over the sequence): read as 12-bit, 4095 scaled to 255" in err
    assert min(_Seeing.seen) > 180 and "nearly black" not in err
    # true 16-bit frames are read as before (their top 8 bits), 8-bit ones too: no note
    assert frame_depth(sorted(_frames(tmp_path / "f16", [60000, 65535], dtype=np.uint16).iterdir())) == (16, 65535)
    assert frame_depth(sorted(_frames(tmp_path / "f8", [200, 255]).iterdir())) is None
    code, out, err = run_cli("tool", "track", tmp_path / "f16", "--model", stub, "--out", tmp_path / "q.csv")
    assert code == 0 and err == "", err


def test_track_says_when_frames_are_unlike_the_models(tmp_path, run_cli, stub):
    cases = {"dark": (_frames(tmp_path / "dark", [20, 20]), "the frames are nearly black"),
             "grey": (_frames(tmp_path / "grey", [255, 255], grey=True),
                      "the frames are grey, the model's training frames in colour"),
             "turned": (_frames(tmp_path / "turned", [255, 255], size=(64, 48)),
                        "frames of 48x64 for a model trained on frames of 64x48 (turned)")}
    for name, (frames, note) in cases.items():
        code, out, err = run_cli("tool", "track", frames, "--model", stub, "--out", tmp_path / f"{name}.csv")
        assert code == 0 and note in err and err.count("note:") == 1, (name, err)
    code, out, err = run_cli("tool", "track", _frames(tmp_path / "plain", [255, 255]), "--model", stub,
                             "--out", tmp_path / "plain.csv")
    assert code == 0 and err == "", err


def test_a_model_keeps_whether_its_frames_were_grey(tmp_path):
    frames = [np.full((48, 64, 3), 90, np.uint8)] * 2
    heads = [np.array([[20.0, 20.0, 6.0, 0.5]])] * 2
    det = ToolDetector(epochs=1, batch=2, width=4).fit(frames, heads)
    assert det.grey_ is True
    det.save(tmp_path / "m.pt")
    assert ToolDetector.load(tmp_path / "m.pt").grey_ is True
    import torch

    state = torch.load(tmp_path / "m.pt", weights_only=True)
    del state["grey"]  # a model saved before: unknown
    torch.save(state, tmp_path / "old.pt")
    assert ToolDetector.load(tmp_path / "old.pt").grey_ is None
    state["grey"] = "yes"
    torch.save(state, tmp_path / "bad.pt")
    with pytest.raises(InputError, match="damaged tool model"):
        ToolDetector.load(tmp_path / "bad.pt")


def test_annotations_as_spreadsheets_export_them(tmp_path, run_cli):
    """Quoted fields, upper-case names and further columns were refused ('unknown column '"frame"'')."""
    want = read_tools_csv(_write(tmp_path / "plain.csv", "frame,tool,y,x,scale,angle\n" + ROWS))
    quoted = '"frame","tool","y","x","scale","angle"\n' + "".join(
        ",".join(f'"{v}"' for v in row.split(",")) + "\n" for row in ROWS.splitlines())
    for name, text in (("quoted", quoted), ("upper", "Frame,TOOL,Y,X,Scale,Angle\r\n" + ROWS)):
        got = read_tools_csv(_write(tmp_path / f"{name}.csv", text))
        assert got.keys() == want.keys() and all(np.array_equal(got[f], want[f]) for f in want), name
    extra: list = []
    text = "frame,tool,y,x,scale,angle,label,Visible\n" + "".join(r + ",grasper,yes\n" for r in ROWS.splitlines())
    got = read_tools_csv(_write(tmp_path / "extra.csv", text), extra)
    assert extra == ["label", "Visible"] and all(np.array_equal(got[f], want[f]) for f in want)
    pred = _write(tmp_path / "pred.csv", "frame,track,x,y,scale,angle,score\n1175,0,245,122,67.5,5.85,0.9\n")
    code, out, err = run_cli("tool", "eval", tmp_path / "extra.csv", pred)
    assert code == 0 and "extra.csv: columns 'label', 'Visible' not read" in err, err
    # a misspelt column is still missing; the same column twice (in two cases) an error; predictions
    # (artmotion's own) have their columns only
    for text, message in (("frame,tool,y,x,scael,angle\n" + ROWS, "missing column 'scale'"),
                          ("frame,tool,y,x,X,scale,angle\n", "duplicate column 'X'")):
        with pytest.raises(InputError, match=message):
            read_tools_csv(_write(tmp_path / "bad.csv", text))
    with pytest.raises(InputError, match="unknown column 'extra'"):
        read_predictions(_write(tmp_path / "bad.csv", "frame,track,x,y,scale,angle,score,extra\n"))
    with pytest.raises(InputError, match="expected 6 columns, got 7") as info:
        read_tools_csv(_write(tmp_path / "bad.csv", 'frame,tool,y,x,scale,angle\n"1175,0",0,1,2,3,4,5\n'))
    assert info.value.line == 2


def test_too_small_training_frames_are_named(tmp_path, run_cli):
    for size in ((1, 1), (30, 40)):
        folder = tmp_path / f"f{size[1]}x{size[0]}"
        _frames(folder, [200, 200], size=size)
        csv = _write(tmp_path / "tools.csv", "frame,tool,y,x,scale,angle\n1,0,0,0,3,0\n")
        code, out, err = run_cli("tool", "train", folder, csv, "--model", tmp_path / "m.pt", "--epochs", 1)
        assert code == 2 and err.count("\n") == 1, err
        assert f"{folder}: frames of {size[1]}x{size[0]} are too small" in err and "at least 32x32" in err
    assert not (tmp_path / "m.pt").exists()


def _write(path, text):
    path.write_text(text)
    return path


def test_a_16_bit_sequence_that_starts_dark_is_not_read_as_fewer_bits(tmp_path):
    """Frames of a full 16-bit range whose first five stay dark (a fade-in) were taken for 8-bit
    ones, and every later frame read as white; then for 16-bit ones of values up to 50 only, and
    `track` or `run` stopped at the first bright frame. The depth is read from frames spread over
    the sequence and only from values using its top bit; a frame beyond the depth read is an error,
    not clipped."""
    from artmotion.errors import InputError
    from artmotion.io.media import frame_depth, read_frame
    from artmotion.io.sequence import open_sequence

    folder = tmp_path / "fade"
    folder.mkdir()
    paths = []
    for k, top in enumerate([50] * 12 + [20000, 3000, 9000, 60000]):
        p = folder / f"{k:03d}.png"
        cv2.imwrite(str(p), np.full((8, 8, 3), top, np.uint16))
        paths.append(p)
    assert frame_depth(paths) == (16, 60000)
    assert int(read_frame(paths[15], 16).max()) == 60000 >> 8
    assert len(list(open_sequence(folder).frames())) == 16
    twelve = []
    for k, top in enumerate([3000] * 5 + [5000]):
        p = tmp_path / f"t{k:03d}.png"
        cv2.imwrite(str(p), np.full((8, 8, 3), top, np.uint16))
        twelve.append(p)
    assert frame_depth(twelve[:5]) == (12, 3000)
    assert int(read_frame(twelve[0], 12).max()) == round(3000 * 255 / 4095)
    with pytest.raises(InputError, match="values up to 5000: more than the 12 bits"):
        read_frame(twelve[5], 12)


def test_an_angle_beyond_a_million_radians_is_refused(tmp_path):
    """1e30 rad was wrapped to whatever float rounding left (found by a fuzzing review)."""
    p = _write(tmp_path / "t.csv", "frame,tool,y,x,scale,angle\n1,0,10,20,30,1e30\n")
    with pytest.raises(InputError, match="angle must be a number in"):
        read_tools_csv(p)
    p = _write(tmp_path / "u.csv", "frame,tool,y,x,scale,angle\n1,0,10,20,30,-314.15\n")
    assert read_tools_csv(p)[1].shape == (1, 4)

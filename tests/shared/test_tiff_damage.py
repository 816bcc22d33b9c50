"""A TIFF frame whose compressed strips are damaged decoded with wrong pixels, in silence: libtiff
says so only through OpenCV's log, which artmotion keeps quiet (found by a fuzzing review)."""

import cv2
import numpy as np
import pytest

from artmotion._native import quiet_native_logs
from artmotion.errors import InputError
from artmotion.io.media import read_image
from artmotion.io.sequence import open_sequence


def test_a_damaged_tiff_frame_is_an_error(tmp_path):
    quiet_native_logs()                         # as the command line runs
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.integers(0, 255, (240, 320, 3), dtype=np.uint8), (5, 5), 0)
    folder = tmp_path / "frames"
    folder.mkdir()
    for k in (1, 2, 3):
        cv2.imwrite(str(folder / f"{k:06d}.tiff"), img)
    assert read_image(folder / "000002.tiff").shape == (240, 320, 3)
    data = bytearray((folder / "000002.tiff").read_bytes())
    mid = len(data) // 2
    data[mid:mid + 2000] = b"\x55" * 2000
    (folder / "000002.tiff").write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"000002.tiff: corrupt image data \(.*TIFF_Error"):
        read_image(folder / "000002.tiff")
    with pytest.raises(InputError, match="000002.tiff: corrupt image data"):
        list(open_sequence(folder).frames())
    assert cv2.utils.logging.getLogLevel() == cv2.utils.logging.LOG_LEVEL_SILENT    # quiet again

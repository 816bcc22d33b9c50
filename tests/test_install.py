"""The environment keeps OpenCV's contrib build: installing opencv-python (pulled in by trackeval or
trackers) would overwrite it and remove the HOG people detector."""


def test_cv2_has_hog_descriptor():
    import cv2

    assert hasattr(cv2, "HOGDescriptor"), f"cv2 {cv2.__version__} lacks HOGDescriptor: reinstall the contrib wheel"
    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())

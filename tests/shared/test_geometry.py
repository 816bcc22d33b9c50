import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from artmotion.errors import InputError
from artmotion.geometry import (
    angle_between,
    axis_angle_to_matrix,
    box_area,
    box_center,
    box_from_center,
    box_overlap,
    clip_box,
    intersection,
    iou,
    iou_matrix,
    matrix_to_axis_angle,
    matrix_to_quat,
    max_iou,
    overlap_ratio,
    quat_to_matrix,
    union_box,
    xywh_to_xyxy,
    xyxy_to_xywh,
)

coord = st.floats(-1000, 1000, allow_nan=False)
size = st.floats(0.5, 500, allow_nan=False)
box = st.tuples(coord, coord, size, size).map(np.array)


@given(box, box)
def test_iou_symmetric_and_bounded(a, b):
    v = iou(a, b)
    assert 0.0 <= v <= 1.0 + 1e-12
    assert np.isclose(v, iou(b, a))


@given(box)
def test_iou_self_is_one(a):
    assert np.isclose(iou(a, a), 1.0)


@given(box, box)
def test_intersection_not_larger_than_either(a, b):
    inter = intersection(a, b)
    assert inter <= box_area(a) + 1e-6 and inter <= box_area(b) + 1e-6
    assert 0.0 <= overlap_ratio(a, b) <= 1.0 + 1e-12


@given(box)
def test_xyxy_roundtrip_and_center(a):
    np.testing.assert_allclose(xyxy_to_xywh(xywh_to_xyxy(a)), a, atol=1e-9)
    np.testing.assert_allclose(box_from_center(box_center(a), a[2:]), a, atol=1e-9)


@given(st.lists(box, min_size=1, max_size=6))
def test_union_box_contains_members(boxes):
    u = union_box(boxes)
    for b in boxes:
        assert np.isclose(overlap_ratio(b, u), 1.0)


@given(box, st.lists(box, max_size=40))
def test_scalar_helpers_equal_the_array_functions(a, boxes):
    # the tracker's per-box fast paths must give the very same numbers (its outputs depend on them)
    assert max_iou(a, boxes) == (iou_matrix(a, boxes).max() if boxes else 0.0)
    for b in boxes:
        assert box_overlap(a, b) == float(overlap_ratio(a, b))
    assert box_overlap([0, 0, 0, 5], [0, 0, 10, 10]) == 0.0      # an empty box is covered by nothing


def test_iou_known_values():
    assert np.isclose(iou([0, 0, 10, 10], [5, 0, 10, 10]), 50 / 150)
    assert iou([0, 0, 10, 10], [20, 20, 5, 5]) == 0.0
    m = iou_matrix([[0, 0, 10, 10], [100, 100, 5, 5]], [[0, 0, 10, 10]])
    assert m.shape == (2, 1) and m[0, 0] == 1.0 and m[1, 0] == 0.0


def test_clip_box():
    np.testing.assert_allclose(clip_box([-5, -5, 20, 20], 10, 10), [0, 0, 10, 10])


@settings(max_examples=50)
@given(st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(lambda v: np.linalg.norm(v) > 0.1),
       st.floats(0.01, 3.1))
def test_axis_angle_roundtrip(axis, angle):
    R = axis_angle_to_matrix(axis, angle)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-9)
    ax, an = matrix_to_axis_angle(R)
    assert np.isclose(an, angle, atol=1e-7)
    np.testing.assert_allclose(ax, np.asarray(axis) / np.linalg.norm(axis), atol=1e-6)
    np.testing.assert_allclose(quat_to_matrix(matrix_to_quat(R)), R, atol=1e-9)


def test_non_unit_quaternion_is_rejected():
    try:
        quat_to_matrix([0, 0, 0, 2])
    except InputError as exc:
        assert "non-unit" in str(exc)
    else:
        raise AssertionError("expected InputError")


def test_angle_between():
    assert np.isclose(angle_between([1, 0, 0], [0, 1, 0]), np.pi / 2)
    assert np.isclose(angle_between([1, 1, 0], [2, 2, 0]), 0.0, atol=1e-7)


def test_rotation_checks_take_no_tolerance_that_accepts_anything():
    """``tol=nan`` (or inf) passed every matrix: diag(5, 1, 1) became the identity quaternion."""
    from artmotion.errors import InputError
    from artmotion.geometry import check_rotations, matrix_to_quat, quat_to_matrix, rotation_angle

    for tol in (float("nan"), float("inf"), 0.0, -1.0):
        calls = (lambda t: matrix_to_quat(np.diag([5.0, 1, 1]), tol=t), lambda t: rotation_angle(np.eye(3), tol=t),
                 lambda t: quat_to_matrix([0.0, 0, 0, 1], tol=t), lambda t: check_rotations(np.eye(3), tol=t))
        for call in calls:
            with pytest.raises(InputError, match="tol must be"):
                call(tol)
    for q in (None, [0.0, 0, 1], "abcd"):
        with pytest.raises(InputError, match="quaternions must be"):
            quat_to_matrix(q)
    np.testing.assert_allclose(matrix_to_quat(np.eye(3)), [0, 0, 0, 1])


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_box_with_nan_or_infinity_is_refused_not_scored_zero(bad):
    """A NaN box used to have IoU 0 with everything (the division skipped a NaN union). A size of
    -inf is a negative size, an empty box, like any other."""
    from artmotion.geometry import boxes as B
    good = [10.0, 10.0, 20.0, 30.0]
    for k in range(2 if bad == -np.inf else 4):
        box = list(good)
        box[k] = bad
        calls = [(B.iou, box, good), (B.iou, good, box), (B.iou_matrix, [box], [good]),
                 (B.overlap_ratio, box, good), (B.overlap_ratio, good, box), (B.max_iou, good, [box]),
                 (B.max_iou, box, [good]), (B.max_iou, good, [box] * 20), (B.box_overlap, box, good),
                 (B.box_overlap, good, box)]
        for f, a, b in calls:
            with pytest.raises(InputError, match="finite"):
                f(a, b)

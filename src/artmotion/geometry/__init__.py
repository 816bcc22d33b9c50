"""Shared geometry: axis-aligned boxes, 2-D affine maps (:mod:`~artmotion.geometry.affine`) and 3-D rotations."""

from artmotion.geometry.boxes import (
    box_area,
    box_center,
    box_from_center,
    box_overlap,
    clip_box,
    intersection,
    iou,
    iou_matrix,
    max_iou,
    overlap_ratio,
    union_box,
    xywh_to_xyxy,
    xyxy_to_xywh,
)
from artmotion.geometry.rotations import (
    angle_between,
    axis_angle_to_matrix,
    check_rotations,
    matrix_to_axis_angle,
    matrix_to_quat,
    quat_to_matrix,
    rotation_angle,
)

__all__ = [
    "angle_between",
    "axis_angle_to_matrix",
    "box_area",
    "box_center",
    "box_from_center",
    "box_overlap",
    "check_rotations",
    "clip_box",
    "intersection",
    "iou",
    "iou_matrix",
    "matrix_to_axis_angle",
    "matrix_to_quat",
    "max_iou",
    "overlap_ratio",
    "quat_to_matrix",
    "rotation_angle",
    "union_box",
    "xywh_to_xyxy",
    "xyxy_to_xywh",
]

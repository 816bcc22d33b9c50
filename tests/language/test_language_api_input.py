"""Bad input to the language API (describe, pose_changes, the grounding models) is an InputError
naming the parameter; valid input reads as before."""

import math

import numpy as np
import pytest

from artmotion.errors import InputError
from artmotion.language.describe import DescribeParams, describe, pose_changes
from artmotion.language.grammar import noun_phrase
from artmotion.language.grounding import CompositionalSparse, PairedSparse, estimate_linking

FRAMES = np.arange(1, 41)
# one track walking right over frames 1-40
TRACK = np.column_stack([FRAMES, np.ones(40), 100 + 5 * FRAMES, np.full(40, 200), np.full(40, 30), np.full(40, 60),
                         np.ones(40), -np.ones((40, 3))])
POSE_FRAMES = np.arange(1, 31)
POSE_ANGLES = np.r_[np.zeros(10), np.full(10, 60.0), np.zeros(10)]


def sentences(triplets):
    return [t.sentence for t in triplets]


def test_describe_tells_the_pose_of_a_clean_sequence():
    assert sentences(describe(TRACK, pose=(POSE_FRAMES, POSE_ANGLES))) == [
        "Person 1 moves right from frame 1 to frame 40.", "Tool opens at frame 11.", "Tool closes at frame 21."]


def test_a_nan_angle_is_refused_not_silently_dropping_every_pose_sentence():
    bad = POSE_ANGLES.copy()
    bad[4] = np.nan
    with pytest.raises(InputError, match=r"pose angles must be finite.*got nan at frame 5"):
        describe(TRACK, pose=(POSE_FRAMES, bad))
    with pytest.raises(InputError, match="pose angles must be finite"):
        pose_changes(POSE_FRAMES, np.where(POSE_ANGLES > 0, np.inf, 0.0))


def test_frames_and_angles_of_different_lengths_are_refused_not_cut_by_zip():
    with pytest.raises(InputError, match="got 8 frames and 30 angles"):
        describe(TRACK, pose=(POSE_FRAMES[:8], POSE_ANGLES))
    with pytest.raises(InputError, match="got 30 frames and 29 angles"):
        pose_changes(POSE_FRAMES, POSE_ANGLES[:-1])


def test_an_empty_pose_sequence_says_nothing_about_the_pose():
    assert sentences(describe(TRACK, pose=([], []))) == ["Person 1 moves right from frame 1 to frame 40."]
    assert pose_changes([], []) == []
    assert pose_changes(np.zeros(0), np.zeros(0), open_above=30, close_below=10) == []


@pytest.mark.parametrize("frames, what", [(POSE_FRAMES + 0.5, "be whole numbers"), (POSE_FRAMES - 1, "be whole numbers"),
                                          (POSE_FRAMES[::-1], "increase"), (np.ones(30), "increase")])
def test_pose_frames_must_be_whole_increasing_frame_numbers(frames, what):
    with pytest.raises(InputError, match=f"pose frames must {what}"):
        describe(TRACK, pose=(frames, POSE_ANGLES))


def test_a_pose_that_is_not_a_pair_of_sequences_is_refused():
    for pose in (POSE_FRAMES, (POSE_FRAMES, POSE_ANGLES, POSE_ANGLES), 3):
        with pytest.raises(InputError, match=r"pose must be a pair \(frames, angles\)"):
            describe(TRACK, pose=pose)
    with pytest.raises(InputError, match="pose angles must be an array of numbers"):
        describe(TRACK, pose=(POSE_FRAMES, ["open"] * 30))
    with pytest.raises(InputError, match="1-D"):
        describe(TRACK, pose=(POSE_FRAMES[:, None], POSE_ANGLES))


@pytest.mark.parametrize("name", ["open_above", "close_below"])
@pytest.mark.parametrize("value", [math.nan, math.inf, "30", 1e7])
def test_thresholds_must_be_finite_angles(name, value):
    with pytest.raises(InputError, match=f"{name} must be a number"):
        describe(TRACK, pose=(POSE_FRAMES, POSE_ANGLES), **{name: value})
    with pytest.raises(InputError, match=f"{name} must be a number"):
        pose_changes(POSE_FRAMES, POSE_ANGLES, **{name: value})


def test_crossed_thresholds_name_the_api_parameters():
    with pytest.raises(InputError, match="close_below 20 is above open_above 5"):
        describe(TRACK, pose=(POSE_FRAMES, POSE_ANGLES), open_above=5, close_below=20)
    with pytest.raises(InputError, match=r"close_below 21 \(automatic\) is above open_above 5"):
        pose_changes(POSE_FRAMES, POSE_ANGLES, open_above=5)
    with pytest.raises(InputError, match="min_range"):
        pose_changes(POSE_FRAMES, POSE_ANGLES, min_range=-1)


@pytest.mark.parametrize("field, value", [("smooth", 2.5), ("smooth", -1), ("window", 0), ("window", -3),
                                          ("min_segment", 0), ("min_together", 1.5), ("max_gap", -1),
                                          ("near", math.nan), ("still", -0.1), ("min_move", math.inf),
                                          ("diagonal", "0.5"), ("border", 2.0), ("same_velocity", None)])
def test_describe_params_are_checked(field, value):
    with pytest.raises(InputError, match=rf"params\.{field} must be"):
        describe(TRACK, params=DescribeParams(**{field: value}))


def test_describe_params_take_whole_floats_and_must_be_describe_params():
    assert sentences(describe(TRACK, params=DescribeParams(smooth=5.0, window=10.0))) == sentences(describe(TRACK))
    with pytest.raises(InputError, match="params must be a DescribeParams"):
        describe(TRACK, params={"smooth": 3})


def test_class_names_must_be_text():
    with pytest.raises(InputError, match="class of track 1 must be text"):
        describe(TRACK, classes=("person", {1: 5}))
    with pytest.raises(InputError, match="default class must be text"):
        describe(TRACK, classes=(None, {}))
    with pytest.raises(InputError, match="track id must be a whole number"):
        describe(TRACK, classes=("person", {"1": "cart"}))
    for classes in (("per\nson", {}), ("person", {1: "ca\nrt"})):
        with pytest.raises(InputError, match="a class name: letters, spaces and hyphens"):
            describe(TRACK, classes=classes)
    for subject in (7, "x\ny", "", "tool 3"):     # (a line break split a sentence over two lines)
        with pytest.raises(InputError, match="pose_subject must be a class name"):
            describe(TRACK, pose=(POSE_FRAMES, POSE_ANGLES), pose_subject=subject)
    with pytest.raises(InputError, match="pose_track must be a whole number"):
        describe(TRACK, pose=(POSE_FRAMES, POSE_ANGLES), pose_track=1.5)
    with pytest.raises(InputError, match="class name must be text"):
        noun_phrase(3, 1, capital=True)
    assert sentences(describe(TRACK, classes=("person", {1: "cart"})))[0] == "Cart 1 moves right from frame 1 to frame 40."


# -- grounding -------------------------------------------------------------------------------------

RNG = np.random.default_rng(0)
C, S = RNG.normal(size=(30, 3)), RNG.normal(size=(30, 5))
A1, A2 = RNG.normal(size=(30, 4)), RNG.normal(size=(30, 4))


def test_blocks_of_different_examples_name_the_block():
    with pytest.raises(InputError, match="visual concept 2 has 20 examples"):
        CompositionalSparse(n_atoms=4).fit([C, S[:20]], [A1, A2])
    with pytest.raises(InputError, match="audio segment 2 has 29 examples"):
        CompositionalSparse(n_atoms=4).fit([C, S], [A1, A2[:29]])
    with pytest.raises(InputError, match="audio segment 1 has 5 examples"):
        estimate_linking([C, S], [A1[:5], A2])


def test_one_array_instead_of_a_list_of_blocks_is_refused():
    with pytest.raises(InputError, match=r"visual must be a list of feature arrays, one per concept, got ndarray of "
                                         r"shape \(30, 3\)"):
        CompositionalSparse(n_atoms=4).fit(C, A1)
    with pytest.raises(InputError, match="audio must be a list of feature arrays"):
        estimate_linking([C], A1)


@pytest.mark.parametrize("params, name", [(dict(n_atoms=0), "n_atoms"), (dict(n_atoms=2.5), "n_atoms"),
                                          (dict(lam=-1), "lam"), (dict(lam=math.nan), "lam"),
                                          (dict(max_iter=-1), "max_iter"), (dict(seed=-1), "seed")])
def test_sparse_model_parameters_are_named(params, name):
    with pytest.raises(InputError, match=f"{name} must be"):
        PairedSparse(**params).fit(C, A1)
    with pytest.raises(InputError, match=f"{name} must be"):
        CompositionalSparse(**params).fit([C, S], [A1, A2])


def test_estimate_linking_errors_are_input_errors():
    with pytest.raises(InputError, match="as many visual concepts as audio segments"):
        estimate_linking([C], [A1, A2])
    bad = C.copy()
    bad[3, 1] = np.nan
    with pytest.raises(InputError, match="visual concept 1 features contain NaN"):
        estimate_linking([bad, S], [A1, A2])
    with pytest.raises(InputError, match="seed must be"):
        estimate_linking([C, S], [A1, A2], seed=-1)


def test_a_fitted_compositional_model_wants_a_list_of_blocks():
    m = CompositionalSparse(n_atoms=3, max_iter=3).fit([C, S], [A1, A2], H=np.eye(2, dtype=int))
    assert [g.shape for g in m.audio_to_visual([A1[:2], A2[:2]])] == [(2, 3), (2, 5)]
    with pytest.raises(InputError, match="expected a list of 2 audio segments"):
        m.audio_to_visual(A1[:2])


@pytest.mark.parametrize("cls", ["PairedSparse", "CompositionalSparse"])
def test_grounding_models_are_scikit_learn_estimators(cls):
    """clone, get_params/set_params and a repr of the parameters (sklearn's clone raised TypeError)."""
    import pickle

    from sklearn.base import clone

    from artmotion.language.grounding import sparse

    est = getattr(sparse, cls)(n_atoms=8, lam=0.2)
    assert est.get_params() == {"n_atoms": 8, "lam": 0.2, "max_iter": 60, "seed": 0}
    assert repr(est) == f"{cls}(lam=0.2, n_atoms=8)"
    assert est.set_params(seed=3) is est and est.seed == 3
    if cls == "PairedSparse":
        rng = np.random.default_rng(0)
        X, Y = rng.normal(size=(40, 6)), rng.normal(size=(40, 5))
        est.fit(X, Y)
        again = pickle.loads(pickle.dumps(est))
        np.testing.assert_array_equal(again.visual_to_audio(X), est.visual_to_audio(X))
    fresh = clone(est)
    assert fresh.get_params() == est.get_params() and not any(k.endswith("_") for k in vars(fresh))


def test_describe_refuses_an_event_given_twice_as_an_events_file_does():
    # the same enter event twice was told twice ("a person enters ... " two times); read_events
    # refuses a repeated line, describe's API took the same list
    rows = np.array([[f, 1, 10.0 + 5 * f, 50.0, 20.0, 40.0, 1, -1, -1, -1] for f in range(1, 30)])
    ev = {"type": "enter", "frame": 1, "tracks": [1], "side": "left"}
    assert describe(rows, [ev], fps=25.0, image_size=(320, 240))      # once: fine
    with pytest.raises(InputError, match=r"event 2: the same event as event 1 \(repeated\)"):
        describe(rows, [ev, dict(ev)], fps=25.0, image_size=(320, 240))


def test_describe_tells_an_event_once_whatever_else_it_carries():
    # the repeat check took json.dumps of the whole event: keys of mixed types crashed it (a bare
    # TypeError), arrays that differ in their middle looked alike in repr, events of types outside
    # the grammar (passed over, unread) were refused, and frame 1 and np.int64(1) looked different
    rows = np.array([[f, 1, 10.0 + 5 * f, 50.0, 20.0, 40.0, 1, -1, -1, -1] for f in range(1, 30)])
    ev = {"type": "enter", "frame": 1, "tracks": [1], "side": "left"}
    kw = {"fps": 25.0, "image_size": (320, 240)}
    assert describe(rows, [{**ev, "extra": {"a": 1, 3: "k"}}], **kw)
    note = {"type": "note", "frame": 1, "tracks": [1]}
    assert describe(rows, [ev, note, dict(note)], **kw) == describe(rows, [ev], **kw)
    with pytest.raises(InputError, match=r"event 2: the same event as event 1 \(repeated\)"):
        describe(rows, [ev, {**ev, "frame": np.int64(1), "tracks": [np.int64(1)]}], **kw)
    # a type or side given as a 0-d array compared equal to its text and crashed the grammar
    for key in ("type", "side"):
        with pytest.raises(InputError, match=f"event 1: unknown {'event type' if key == 'type' else 'side'}"):
            describe(rows, [{**ev, key: np.array(ev[key])}], **kw)
    assert describe(rows, [{**ev, "side": np.str_("left")}], **kw) == describe(rows, [ev], **kw)
    a, b = np.zeros(2000), np.zeros(2000)
    b[1000] = 1      # what describe does not read makes no other event of it: still the same event
    with pytest.raises(InputError, match="the same event as event 1"):
        describe(rows, [{**ev, "blob": a}, {**ev, "blob": b}], **kw)


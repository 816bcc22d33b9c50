"""The 30 real gripper trajectories of Sturm et al. (2010): every log classified right, online, and
decided (for good) by a quarter of the log in the median.

Skipped when ../shared/data/articulation/sturm2010 is absent.
"""

from collections import defaultdict

import numpy as np

from artmotion.articulation.online import estimate_online

from conftest import shared_path

TRUTH = {"dishwasher": "revolute", "drawer": "prismatic", "left_door": "revolute", "right_door": "revolute"}


def test_every_log_classified_and_decided_early():
    root = shared_path("articulation", "sturm2010")
    fractions, radii = [], defaultdict(list)
    logs = sorted(root.glob("*/*.log"))
    assert len(logs) >= 30
    for log in logs:
        X = np.loadtxt(log)
        res = estimate_online(X)
        truth = TRUTH[log.parent.name]
        assert res.model == truth, (log, res.probabilities)
        fractions.append(res.decided_at / len(X))
        if truth == "revolute":
            radii[log.parent.name].append(res.configuration["radius"])
    assert np.median(fractions) <= 0.25
    # (left_door/003's Student-t optimum lies at 0.383 m, 0.04 from the others' median, and its
    # radius creeps there by a few mm a re-weighting: 0.371 from a plain start, 0.374 from the
    # smooth-motion weights; the others move by 1 mm at most)
    for name, r in radii.items():
        assert np.abs(np.array(r) - np.median(r)).max() <= 0.035, (name, r)

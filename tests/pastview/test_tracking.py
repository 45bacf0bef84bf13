from pastview.tracking import PoseTracker, Transition

LEVEL = [0.0, 0.0, 0.0, 1.0]


def test_the_first_pose_counts_as_tracked_without_a_transition():
    tracker = PoseTracker()

    assert tracker.update([0, 0, 0], LEVEL) is None
    assert tracker.tracked


def test_tracking_is_lost_when_a_pose_repeats_exactly_and_found_on_the_next_change():
    tracker = PoseTracker()
    events = [
        tracker.update([0, 0, 0], LEVEL),
        tracker.update([0.1, 0, 0], LEVEL),
        tracker.update([0.1, 0, 0], LEVEL),  # the tracker froze: same pose, new time stamp
        tracker.update([0.1, 0, 0], LEVEL),
        tracker.update([0.2, 0, 0], LEVEL),
        tracker.update([0.3, 0, 0], LEVEL),
    ]

    assert events == [None, None, Transition.LOST, None, Transition.FOUND, None]
    assert tracker.tracked
    assert tracker.lost_count == 1


def test_a_change_of_orientation_alone_keeps_tracking():
    tracker = PoseTracker()
    tracker.update([1, 1, 1], LEVEL)

    assert tracker.update([1, 1, 1], [0.0, 0.0, 0.1, 0.995]) is None
    assert tracker.tracked


def test_a_lost_tracker_reports_lost_until_the_pose_changes():
    tracker = PoseTracker()
    tracker.update([1, 1, 1], LEVEL)
    tracker.update([1, 1, 1], LEVEL)

    assert not tracker.tracked
    assert tracker.update([1, 1, 1], LEVEL) is None
    assert not tracker.tracked

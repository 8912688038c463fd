"""Failure kinds and the field's metrics of a trial (pd_campaign.outcome), on hand-made records
whose answers are worked out by hand."""

import pytest


from pd_campaign import outcome  # noqa: E402

INNER = 6.0e-3  # inner layer's entry, 6 mm below the surface; its end at 8 mm


def truth(*rows, end_mm=8.0):
    """(t, layer, max_depth mm) -> rows with residual and breakthrough as the simulator has them
    (the inner layer from 6 mm to end_mm)."""
    out = []
    for t, layer, depth_mm in rows:
        depth = depth_mm * 1e-3
        residual = max(0.0, end_mm * 1e-3 - depth)
        out.append((t, layer, depth, residual, layer == 'canal', 0.0, True, 0))
    return out


RECOGNIZER = 'inner cortical layer reached: stop after key point 4'


def test_success_and_its_metrics():
    rows = truth((0.0, 'air', 0.0), (10.0, 'inner_cortical', 6.0), (11.0, 'inner_cortical', 6.5),
                 (12.0, 'inner_cortical', 6.6))
    kind, m = outcome.classify(rows, [(11.0, '/state_recognizer', RECOGNIZER, False)], INNER, True)
    assert kind == 'success'
    assert m['stop_depth_mm'] == pytest.approx(6.5)
    assert m['stop_residual_mm'] == pytest.approx(1.5)
    assert m['overshoot_mm'] == pytest.approx(0.6)
    assert m['rundown_mm'] == pytest.approx(0.1)
    assert m['detection_latency_ms'] == pytest.approx(1000.0)


def test_breakthrough_before_and_after_the_stop_command():
    rows = truth((0.0, 'air', 0.0), (10.0, 'inner_cortical', 6.0), (14.0, 'canal', 8.0),
                 (15.0, 'canal', 8.2))
    before = [(14.5, '/state_recognizer', RECOGNIZER, False)]
    after = [(13.0, '/state_recognizer', RECOGNIZER, False)]
    assert outcome.classify(rows, before, INNER, False)[0] == 'breakthrough_before_stop'
    assert outcome.classify(rows, after, INNER, False)[0] == 'breakthrough_after_stop'
    # Never stopped: a breakthrough is still a breakthrough; without one, no_stop.
    assert outcome.classify(rows, [], INNER, False)[0] == 'breakthrough_before_stop'
    intact = truth((0.0, 'air', 0.0), (30.0, 'cancellous', 5.0))
    assert outcome.classify(intact, [], INNER, False)[0] == 'no_stop'


def test_a_safety_stop_before_a_breakthrough_is_a_breakthrough_after_the_stop():
    # The first stop was H1, then the bone ran into the drill: the perforation is what counts.
    rows = truth((0.0, 'air', 0.0), (10.0, 'inner_cortical', 6.0), (11.0, 'canal', 8.0))
    h1 = (10.5, '/safety_monitor', 'position_error: bone position error 1.25 mm > 1.2 mm', True)
    kind, m = outcome.classify(rows, [h1], INNER, False)
    assert kind == 'breakthrough_after_stop'
    assert outcome.first_stop_kind([h1]) == 'safety_h1'
    assert m['detection_latency_ms'] == pytest.approx(500.0)


def test_entry_after_the_stop_command_gives_a_negative_latency():
    rows = truth((0.0, 'air', 0.0), (9.0, 'cancellous', 5.9), (9.4, 'inner_cortical', 6.0),
                 (9.6, 'inner_cortical', 6.05))
    kind, m = outcome.classify(rows, [(9.2, '/state_recognizer', RECOGNIZER, False)], INNER,
                               False)
    assert m['detection_latency_ms'] == pytest.approx(-200.0)
    assert m['rundown_mm'] == pytest.approx(0.15)


def test_early_and_shallow_stops():
    early = truth((0.0, 'air', 0.0), (5.0, 'cancellous', 4.0))
    kind, m = outcome.classify(early, [(5.0, '/state_recognizer', RECOGNIZER, False)], INNER,
                               False)
    assert kind == 'stopped_before_inner'
    assert m['detection_latency_ms'] is None and m['overshoot_mm'] is None
    assert m['stop_residual_mm'] == pytest.approx(4.0)
    shallow = truth((0.0, 'air', 0.0), (10.0, 'inner_cortical', 6.0),
                    (10.2, 'inner_cortical', 6.1), end_mm=8.5)  # 2.4 mm left
    kind, m = outcome.classify(shallow, [(10.2, '/state_recognizer', RECOGNIZER, False)], INNER,
                               False)
    assert kind == 'stopped_shallow'
    assert m['detection_latency_ms'] == pytest.approx(200.0)


@pytest.mark.parametrize('stop, kind', [
    ((5.0, '/safety_monitor', 'position_error: bone position error 1.304 mm > 1.200 mm at t=5 s',
      True), 'safety_h1'),
    ((5.0, '/safety_monitor', 'force_exceeded: thrust 10.4 N', True), 'safety_h2'),
    ((5.0, '/safety_monitor', 'tracker_timeout: no tracker sample', True), 'safety_watchdog'),
    ((5.0, '/compensation_planner', 'recognizer silent: no drilling_state', True),
     'safety_watchdog'),
    ((5.0, '/compensation_planner', 'implausible force: the recognizer still reports', True),
     'safety_plausibility'),
    ((5.0, '/state_recognizer', 'implausible force: cancellous bone not confirmed', False),
     'safety_plausibility'),
    ((5.0, '/compensation_planner', 'depth_limit: the tip reached the plan\'s depth (planned '
      'depth 7.1 mm from the surface at 5.2 mm of advance (no contact sensed: the '
      'registration\'s shallow end))', True), 'safety_depth_limit'),
])
def test_safety_stops_by_source_and_reason(stop, kind):
    rows = truth((0.0, 'air', 0.0), (5.0, 'cancellous', 4.0))
    assert outcome.classify(rows, [stop], INNER, False)[0] == kind


def test_h1_error_is_read_from_the_reason():
    assert outcome.h1_error_mm('position_error: bone position error 1.304 mm > 1.200 mm') == \
        pytest.approx(1.304)
    assert outcome.h1_error_mm('force_exceeded: 11 N') is None


@pytest.mark.parametrize('source, reason, line', [
    ('/state_recognizer', 'inner cortical layer reached', 'recognizer'),
    ('/compensation_planner', 'depth_limit: the tip reached the plan\'s depth', 'depth limit'),
    ('/compensation_planner', 'implausible force: the recognizer still reports', 'plausibility bound'),
    ('/safety_monitor', 'position_error: 1.3 mm', 'safety monitor'),
    ('/drill_guard', 'planner_lost', 'safety monitor'),
    ('/compensation_planner', 'recognizer silent', 'other'),
    ('none', 'max_duration', 'no stop'),
])
def test_the_line_that_stopped_the_drill(source, reason, line):
    from pd_campaign import aggregate
    assert aggregate.stop_line({'stop_source': source, 'stop_reason': reason}) == line

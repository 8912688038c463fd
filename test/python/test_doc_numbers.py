"""The documents' generated numbers (scripts/dev/doc_numbers.py) on a small archive written
here, and on the shipped documents: a number changed by hand fails `make_docs.py --check`."""
import csv
import json
import os

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))

import doc_numbers  # noqa: E402
import make_docs  # noqa: E402

GROUPS = [
    {'case': 'stationary', 'rpm': 12000.0, 'successes': 19, 'trials': 20, 'median_f_in_n': 2.0,
     'failure_kinds': {'success': 19, 'stopped_shallow': 1}, 'quartiles_x': [1.0, 2.5, 4.0]},
    {'case': 'compensated', 'rpm': 12000.0, 'successes': 17, 'trials': 20, 'median_f_in_n': 1.5,
     'failure_kinds': {'success': 17, 'breakthrough_before_stop': 3}, 'quartiles_x': [0, 0, 0]},
]
# index, case, success, stop_source, max_depth_mm, inner_start_mm
ROWS = [(0, 'stationary', 'true', '/state_recognizer', 6.0, 4.0),
        (1, 'stationary', 'true', '/state_recognizer', 6.5, 4.0),
        (2, 'stationary', 'false', '/state_recognizer', 5.0, 4.0),
        (0, 'compensated', 'false', '/safety_monitor', 4.5, 4.0),
        (1, 'compensated', 'true', '/state_recognizer', 7.0, 4.0),
        (2, 'compensated', 'true', '/compensation_planner', 9.5, 4.0)]


FAULTS = [dict(GROUPS[1], fault='none'),
          dict(GROUPS[1], fault='force_drift', successes=5, drift_detected=20)]
# A second campaign on the same seeds: compensated succeeds at indices 0 and 2.
OTHER_ROWS = [(0, 'compensated', 'true', '/state_recognizer', 6.0, 4.0),
              (1, 'compensated', 'false', '/safety_monitor', 4.5, 4.0),
              (2, 'compensated', 'true', '/state_recognizer', 6.0, 4.0)]
# campaign_sensitivity's sensitivity.csv, the columns a number reads.
SWEEP = [{'case': 'compensated', 'rpm': '12000', 'constant': 'simulator_params.k',
          'successes_low': '18', 'successes_high': '15', 'mcnemar_p_high': '0.0625'},
         {'case': 'stationary', 'rpm': '12000', 'constant': 'simulator_params.k',
          'successes_low': '19', 'successes_high': '14', 'mcnemar_p_high': '0.0313'}]


def write_trials(folder, rows):
    with open(folder / 'trials.csv', 'w') as handle:
        writer = csv.writer(handle)
        writer.writerow(['index', 'case', 'rpm', 'success', 'stop_source', 'max_depth_mm',
                         'inner_start_mm'])
        for index, case, success, source, depth, inner in rows:
            writer.writerow([index, case, '12000', success, source, depth, inner])


@pytest.fixture
def archive(tmp_path):
    for name, rows in (('bench', ROWS), ('other', OTHER_ROWS)):
        folder = tmp_path / name
        folder.mkdir()
        (folder / 'summary.json').write_text(json.dumps({'groups': GROUPS, 'faults': FAULTS}))
        write_trials(folder, rows)
    (tmp_path / 'sweep').mkdir()
    with open(tmp_path / 'sweep' / 'sensitivity.csv', 'w') as handle:
        writer = csv.DictWriter(handle, fieldnames=list(SWEEP[0]))
        writer.writeheader()
        writer.writerows(SWEEP)
    return str(tmp_path)


@pytest.mark.parametrize('spec, expected', [
    ('bench stationary 12000 successes', '19'),
    ('bench compensated 12000 median_f_in_n .2f', '1.50'),
    ('bench compensated 12000 median_f_in_n .0%', '150 %'),
    ('bench compensated 12000 failure_kinds.breakthrough_before_stop', '3'),
    ('bench stationary 12000 failure_kinds.breakthrough_before_stop', '0'),  # did not occur
    ('bench stationary 12000 quartiles_x.1 .1f', '2.5'),
    ('bench compensated 12000 count', '3'),
    ('bench compensated 12000 count stop_source=/safety_monitor', '1'),
    ('bench stationary 12000 count success=true,stop_source=/state_recognizer', '2'),
    ('bench compensated 12000 max max_depth_mm-inner_start_mm .1f', '5.5'),
    ('bench compensated 12000 max max_depth_mm .1f WHERE stop_source=/state_recognizer', '7.0'),
    ('bench compensated 12000 only stationary', '1'),   # index 2
    ('bench stationary 12000 only compensated', '1'),   # index 0
    ('bench compensated 12000 mcnemar stationary .2f', '1.00'),
    ('bench compensated 12000 change median_f_in_n .0f', '-25'),
    ('bench compensated 12000 fisher 19/20 .3f', '0.605'),
    ('bench compensated/force_drift 12000 successes', '5'),
    ('bench compensated/force_drift 12000 drift_detected', '20'),
    ('bench compensated/none 12000 drift_detected', '0'),
    ('bench compensated 12000 only other:compensated', '1'),   # index 1
    ('other compensated 12000 only bench:compensated', '1'),   # index 0
    ('bench compensated 12000 mcnemar other:compensated .2f', '1.00'),
    ('sweep compensated 12000 sweep simulator_params.k successes_high', '15'),
    ('sweep stationary 12000 sweep simulator_params.k mcnemar_p_high .2g', '0.031'),
])
def test_a_number_is_read_from_the_archive(archive, spec, expected):
    assert doc_numbers.value(spec, archive) == expected


@pytest.mark.parametrize('spec, error', [
    ('bench stationary', ValueError),                    # too few words
    ('bench uncompensated 12000 successes', KeyError),   # no such group
    ('missing stationary 12000 successes', FileNotFoundError),
    ('bench compensated/force_nan 12000 successes', KeyError),   # no such fault
    ('sweep compensated 12000 sweep simulator_params.x successes_low', KeyError),
])
def test_a_bad_spec_is_an_error_naming_it(archive, spec, error):
    with pytest.raises(error):
        doc_numbers.value(spec, archive)


def test_a_sentence_is_rewritten_and_its_specs_listed(archive):
    text = ('In <!-- n: bench stationary 12000 successes -->18<!-- /n --> of '
            '<!-- n: bench stationary 12000 trials -->20<!-- /n --> trials.')
    new, specs = doc_numbers.regenerate(text, archive)
    assert new == text.replace('-->18<', '-->19<')
    assert specs == ['bench stationary 12000 successes', 'bench stationary 12000 trials']


def test_a_shipped_number_changed_by_hand_fails_the_check():
    path = os.path.join(ROOT, 'doc', 'campaign_results.md')
    with open(path) as handle:
        text = handle.read()
    match = next(doc_numbers.NUMBER.finditer(text))
    tampered = text.replace(match.group(0),
                            match.group(1) + match.group(3) + '0' + match.group(4), 1)
    rebuilt, _ = make_docs.regenerate(tampered, make_docs.ARCHIVE)
    assert rebuilt == text
    stale = make_docs.stale_parts('doc/campaign_results.md', tampered, rebuilt)
    assert stale and match.group(2) in stale[0]


def test_the_shipped_documents_use_generated_numbers():
    with open(os.path.join(ROOT, 'doc', 'campaign_results.md')) as handle:
        assert len(list(doc_numbers.NUMBER.finditer(handle.read()))) >= 50

"""scripts/volunteers_to_bag.py and scripts/table2.py on bad input, as a new user meets it:
exit status 2 and one line naming the option or the file, no traceback, no partial output."""
import os
import subprocess

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
TO_BAG = os.path.join(ROOT, 'scripts', 'volunteers_to_bag.py')
TABLE2 = os.path.join(ROOT, 'scripts', 'table2.py')


def run(script, *args):
    return subprocess.run(['/usr/bin/python3', script] + list(args), capture_output=True,
                          text=True, timeout=120)


def write_recording(folder, vid=1, times=None):
    times = times or [0.125 * i for i in range(40)]
    with open(os.path.join(folder, 'volunteer_%d.csv' % vid), 'w') as f:
        f.write('t,ap,si,lr\n')
        for i, t in enumerate(times):
            f.write('%r,%r,%r,0.0\n' % (t, 0.01 * i, 0.005 * i))
    with open(os.path.join(folder, 'volunteer_%d_tv64.csv' % vid), 'w') as f:
        f.write('t,tv\n')
        for i in range(64 * 5):
            f.write('%r,%r\n' % (i / 64.0, 3.0 * (i % 64)))


def assert_one_line_error(result, *words):
    assert result.returncode == 2, (result.returncode, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert 'Traceback' not in result.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])


def test_a_valid_recording_becomes_a_bag(tmp_path):
    write_recording(str(tmp_path))
    out = tmp_path / 'bags'
    result = run(TO_BAG, '--csv-dir', str(tmp_path), '--out', str(out), '--ids', '1')
    assert result.returncode == 0, result.stderr
    assert os.listdir(str(out)) == ['volunteer_1.bag']


def test_decreasing_time_is_refused_and_no_bag_is_left(tmp_path):
    times = [0.125 * i for i in range(40)]
    times[20], times[21] = times[21], times[20]
    write_recording(str(tmp_path), times=times)
    out = tmp_path / 'bags'
    result = run(TO_BAG, '--csv-dir', str(tmp_path), '--out', str(out), '--ids', '1')
    assert_one_line_error(result, 'volunteer_1.csv', 'does not increase')
    assert os.listdir(str(out)) == []  # no bag, no temporary file


def test_marker_offset_that_is_not_numbers_names_the_option(tmp_path):
    write_recording(str(tmp_path))
    result = run(TO_BAG, '--csv-dir', str(tmp_path), '--out', str(tmp_path / 'o'),
                 '--marker-offset', 'a,b,c')
    assert_one_line_error(result, '--marker-offset')


def test_missing_csv_dir_names_the_option(tmp_path):
    result = run(TO_BAG, '--csv-dir', str(tmp_path / 'nowhere'), '--out', str(tmp_path / 'o'))
    assert_one_line_error(result, '--csv-dir', 'nowhere')
    assert not os.path.exists(str(tmp_path / 'o'))


def test_ids_that_are_not_integers_name_the_option(tmp_path):
    write_recording(str(tmp_path))
    result = run(TO_BAG, '--csv-dir', str(tmp_path), '--out', str(tmp_path / 'o'), '--ids', '1,x')
    assert_one_line_error(result, '--ids')


def test_table2_out_that_cannot_be_created_names_it(tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('not a folder')
    result = run(TABLE2, '--out', str(blocker / 'table'))
    assert_one_line_error(result, '--out', 'a_file')

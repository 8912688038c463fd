"""Fuzzing in `make test`: builds the libFuzzer targets of test/fuzz with clang-14 (ASan, UBSan),
replays the saved crash inputs of test/fuzz/regressions, then fuzzes each target for a bounded
time from its seed corpus (test/fuzz/corpus) in a scratch copy. Any crash, sanitizer report or
broken invariant fails the test and leaves the input in the test artifacts folder.

FUZZ_SECONDS (default 10) sets the time per target: a smoke run in every `make test` (the saved
regressions replayed first); longer runs are for a fuzzing session (doc/development.md, "Tests")."""
import os
import shutil
import subprocess

import pytest

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..')
TARGETS = ('model_yaml', 'recording_csv', 'recognizer')


@pytest.fixture(scope='module')
def fuzz_bin(tmp_path_factory):
    out = os.path.join(ROOT, 'catkin_ws', 'build', 'fuzz')
    build = subprocess.run([os.path.join(ROOT, 'test', 'fuzz', 'build_fuzzers.sh'), out],
                           capture_output=True, text=True, timeout=900)
    assert build.returncode == 0, build.stdout + build.stderr
    return out


@pytest.mark.parametrize('target', TARGETS)
def test_fuzz_target_finds_nothing(fuzz_bin, target, tmp_path):
    binary = os.path.join(fuzz_bin, 'fuzz_' + target)
    artifacts = os.environ.get('PEDICLE_DRILLING_ARTIFACTS', str(tmp_path))
    os.makedirs(artifacts, exist_ok=True)
    prefix = os.path.join(artifacts, 'fuzz_%s-' % target)
    regressions = os.path.join(ROOT, 'test', 'fuzz', 'regressions', target)
    saved = sorted(os.path.join(regressions, f) for f in os.listdir(regressions)) \
        if os.path.isdir(regressions) else []
    if saved:
        replay = subprocess.run([binary] + saved, capture_output=True, text=True, timeout=300)
        assert replay.returncode == 0, replay.stderr[-4000:]
    corpus = tmp_path / 'corpus'
    shutil.copytree(os.path.join(ROOT, 'test', 'fuzz', 'corpus', target), corpus)
    seconds = int(os.environ.get('FUZZ_SECONDS', '10'))
    run = subprocess.run([binary, '-max_total_time=%d' % seconds, '-seed=1',
                          '-artifact_prefix=' + prefix, '-print_final_stats=1', str(corpus)],
                         capture_output=True, text=True, timeout=seconds + 300, cwd=str(tmp_path))
    assert run.returncode == 0, run.stderr[-4000:]
    assert 'Done ' in run.stderr, run.stderr[-2000:]

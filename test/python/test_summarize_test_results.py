"""scripts/dev/summarize_test_results.py: counts and, for a failure, the line that says why."""
import importlib.util
import os

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load():
    spec = importlib.util.spec_from_file_location(
        'summarize', os.path.join(ROOT, 'scripts', 'dev', 'summarize_test_results.py'))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_failure_says_its_assertion(tmp_path, capsys):
    (tmp_path / 'rosunit-x.xml').write_text(
        '<testsuite name="x"><testcase classname="T" name="test_a"/>'
        '<testcase classname="T" name="test_b"><failure type="AssertionError">'
        'Traceback (most recent call last):\n  File "t.py", line 3, in test_b\n'
        '    self.assertFalse(early)\nAssertionError: [1] is not false : a stop before the fault'
        '</failure></testcase></testsuite>')
    assert load().main(str(tmp_path)) == 1
    out = capsys.readouterr().out
    assert 'FAILED rosunit-x.xml: T.test_b\n    AssertionError: [1] is not false : a stop' in out
    assert out.strip().endswith('1 passed, 1 failed')


def test_all_passed(tmp_path, capsys):
    (tmp_path / 'g.xml').write_text('<testsuites><testsuite name="g"><testcase classname="G" '
                                    'name="ok"/></testsuite></testsuites>')
    assert load().main(str(tmp_path)) == 0
    assert capsys.readouterr().out.strip() == '1 passed, 0 failed'

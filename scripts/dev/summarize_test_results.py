#!/usr/bin/python3
"""Counts JUnit XML test cases under a directory and prints `N passed, N failed`.

A test case fails when it has a <failure> or <error> child; a result file that cannot be parsed,
or a test suite that reports errors without any test case (a crashed binary, a rostest whose
test node never started), counts as one failure. Exit status 1 when anything failed or when no
test ran at all."""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def why(problem):
    """The failure's last line that says something (an assertion's message), shortened: so that
    a CI log that keeps only its tail still says why a test failed."""
    text = '\n'.join(t for t in (problem.get('message'), problem.text) if t)
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    said = [line for line in lines if 'Error' in line or 'assert' in line.lower()] or lines
    if not said:
        return ''
    line = said[-1]
    return '\n    ' + (line if len(line) <= 400 else line[:400] + '...')


def main(directory):
    passed = 0
    failed = 0
    skipped = 0
    failures = []
    for path in sorted(glob.glob(os.path.join(directory, '**', '*.xml'), recursive=True)):
        name = os.path.relpath(path, directory)
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as error:
            failed += 1
            failures.append('%s: unreadable result (%s)' % (name, error))
            continue
        suites = [root] if root.tag == 'testsuite' else root.iter('testsuite')
        for suite in suites:
            cases = suite.findall('testcase')
            if not cases:
                if int(suite.get('errors', 0) or 0) + int(suite.get('failures', 0) or 0) > 0:
                    failed += 1
                    failures.append('%s: suite %s failed without test cases'
                                    % (name, suite.get('name')))
                continue
            for case in cases:
                label = '%s: %s.%s' % (name, case.get('classname'), case.get('name'))
                problem = case.find('failure')
                if problem is None:
                    problem = case.find('error')
                if problem is not None:
                    failed += 1
                    failures.append(label + why(problem))
                elif case.find('skipped') is not None:
                    skipped += 1
                else:
                    passed += 1
    for line in failures:
        print('FAILED %s' % line)
    if skipped:
        print('(%d skipped)' % skipped)
    print('%d passed, %d failed' % (passed, failed))
    return 1 if failed or passed == 0 else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else '.'))

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
                if case.find('failure') is not None or case.find('error') is not None:
                    failed += 1
                    failures.append(label)
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

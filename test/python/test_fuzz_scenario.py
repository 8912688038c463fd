"""Fuzzing the scenario loader. libFuzzer fuzzes the C++ readers (test_fuzz.py); the
scenario loader is Python, so it is fuzzed here: seeded mutations of every shipped scenario
file (bytes flipped, inserted, deleted, the file cut short, lines swapped, YAML-significant
characters injected) and random bytes. Every input must give a validated scenario (a dict of
known keys) or a UsageError; anything else (a crash of the loader, a TypeError from an
unchecked value) fails and prints the input. The seed is fixed: the same inputs on every run."""
import glob
import os
import random

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))

from pd_campaign.scenario import SCENARIO_KEYS, UsageError, load_scenario  # noqa: E402

ITERATIONS = int(os.environ.get('FUZZ_SCENARIO_ITERATIONS', '3000'))
SPECIAL = [b':', b'[', b']', b'{', b'}', b'-', b'\n', b' ', b'#', b'"', b"'", b'&a', b'*a',
           b'!!python/object', b'.nan', b'1e400', b'-1', b'0', b'true', b'~', b'\t', b'\x00']


def mutate(data, rng):
    data = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(6)
        pos = rng.randrange(len(data) + 1)
        if op == 0 and data:
            data[min(pos, len(data) - 1)] = rng.randrange(256)
        elif op == 1:
            data[pos:pos] = rng.choice(SPECIAL)
        elif op == 2 and data:
            del data[pos:pos + rng.randint(1, 20)]
        elif op == 3:
            del data[pos:]  # cut short
        elif op == 4:
            lines = bytes(data).split(b'\n')
            if len(lines) > 2:
                i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
                lines[i], lines[j] = lines[j], lines[i]
                data = bytearray(b'\n'.join(lines))
        else:
            data[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 8)))
    return bytes(data)


def test_the_scenario_loader_gives_a_scenario_or_a_usage_error(tmp_path):
    seeds = [open(p, 'rb').read() for p in sorted(glob.glob(os.path.join(ROOT, 'config',
                                                                          'scenario_*.yaml')))]
    assert seeds
    rng = random.Random(20261125)
    path = tmp_path / 'fuzzed.yaml'
    accepted = refused = 0
    for i in range(ITERATIONS):
        data = mutate(rng.choice(seeds), rng) if i % 10 else bytes(
            rng.randrange(256) for _ in range(rng.randint(0, 200)))
        path.write_bytes(data)
        try:
            scenario = load_scenario(str(path))
        except UsageError as error:
            assert str(error).startswith('--scenario'), (data, error)
            assert '\n' not in str(error), (data, error)
            refused += 1
            continue
        except Exception as error:  # the finding: print the input that broke it
            raise AssertionError('load_scenario raised %r on input %r' % (error, data))
        assert isinstance(scenario, dict) and scenario, data
        assert set(scenario) <= set(SCENARIO_KEYS), data
        accepted += 1
    # Both outcomes occur, so the mutations reach the checks behind the parser.
    assert accepted > ITERATIONS // 20 and refused > ITERATIONS // 20, (accepted, refused)

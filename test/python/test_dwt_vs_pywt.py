"""Compare the C++ DWT (dwt_coeffs / denoise CLIs) with PyWavelets.

Run with the Debian interpreter, which has pywt:

    PEDICLE_DRILLING_BIN_DIR=/path/to/bin \\
        /usr/bin/python3 -m pytest -q test/python/test_dwt_vs_pywt.py

The binaries are looked up in $PEDICLE_DRILLING_BIN_DIR, else in this checkout's
catkin_ws/devel/lib/pedicle_drilling. A missing binary or a missing pywt is a
test failure, not a skip.
"""

import math
import os
import subprocess
import warnings

import numpy as np
import pytest

try:
    import pywt
except ImportError:  # pragma: no cover - reported as a failure below
    pywt = None

DEFAULT_BIN_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..',
                               'catkin_ws', 'devel', 'lib', 'pedicle_drilling')
BIN_DIR = os.environ.get("PEDICLE_DRILLING_BIN_DIR", DEFAULT_BIN_DIR)

WAVELETS = (["db%d" % k for k in range(1, 21)] + ["sym%d" % k for k in range(2, 21)] +
            ["coif%d" % k for k in range(1, 6)] +
            ["bior1.1", "bior1.3", "bior1.5", "bior2.2", "bior2.4", "bior2.6", "bior2.8",
             "bior3.1", "bior3.3", "bior3.5", "bior3.7", "bior3.9", "bior4.4", "bior5.5",
             "bior6.8"])
MODES = ["symmetric", "periodization"]
LEVELS = list(range(1, 9))
# (length, levels): every level 1..8 on three lengths, a subset on three more lengths.
SHORT_CASES = [(16, LEVELS), (17, LEVELS), (255, LEVELS), (31, [1, 5, 8]), (100, [2, 6, 8]),
               (1001, [1, 3, 8])]
LONG_LENGTH = 65536
TOL = 1e-9

_stats = {"max_diff": 0.0, "arrays": 0}


def _binary(name):
    path = os.path.join(BIN_DIR, name)
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        pytest.fail("binary %s not found (set PEDICLE_DRILLING_BIN_DIR)" % path)
    return path


def _require_pywt():
    if pywt is None:
        pytest.fail("pywt not importable; run with /usr/bin/python3")


def _signal(n, seed):
    """Seeded test signal of scale ~1: breathing-like sine + drift + white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 8.0
    return (np.sin(2 * np.pi * 0.33 * t) + 0.1 * t / max(t[-1], 1.0) +
            0.3 * rng.standard_normal(n))


def _to_stdin(x):
    return "\n".join(map(repr, np.asarray(x, dtype=float).tolist())) + "\n"


def _run(args, x_text):
    return subprocess.run(args, input=x_text, capture_output=True, text=True, check=False)


def _parse_arrays(stdout):
    lines = stdout.rstrip("\n").split("\n")
    return [np.array(line.split(","), dtype=float) for line in lines]


_LONG = {}


def _long_signal():
    """The 65536-sample signal and its text, computed once per session."""
    if not _LONG:
        x = _signal(LONG_LENGTH, seed=12345)
        _LONG["x"] = x
        _LONG["text"] = _to_stdin(x)
    return _LONG["x"], _LONG["text"]


def _wavedec(x, w, mode, level):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # level above dwt_max_level: pywt warns, we compare
        return pywt.wavedec(x, w, mode=mode, level=level)


def _compare(got, ref, context):
    assert len(got) == len(ref), "%s: %d arrays, pywt %d" % (context, len(got), len(ref))
    worst = 0.0
    for k, (g, r) in enumerate(zip(got, ref)):
        assert g.shape == r.shape, "%s array %d: length %d, pywt %d" % (context, k, g.size,
                                                                         r.size)
        if g.size:
            worst = max(worst, float(np.max(np.abs(g - r))))
    assert worst < TOL, "%s: max abs diff %.3g" % (context, worst)
    _stats["max_diff"] = max(_stats["max_diff"], worst)
    _stats["arrays"] += len(ref)
    return worst


@pytest.fixture(scope="module", autouse=True)
def _report():
    yield
    print("\n[test_dwt_vs_pywt] pywt %s, %d arrays compared, max abs diff %.3g" %
          (getattr(pywt, "__version__", "?"), _stats["arrays"], _stats["max_diff"]))


def test_wavelet_list_known_to_pywt():
    _require_pywt()
    assert len(WAVELETS) == 59
    available = set(pywt.wavelist(kind="discrete"))
    missing = [w for w in WAVELETS if w not in available]
    assert not missing, missing


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_wavedec_matches_pywt(wavelet):
    _require_pywt()
    exe = _binary("dwt_coeffs")
    for n, levels in SHORT_CASES:
        x = _signal(n, seed=n)
        x_text = _to_stdin(x)
        for mode in MODES:
            for level in levels:
                res = _run([exe, "--wavelet", wavelet, "--level", str(level), "--mode", mode],
                           x_text)
                ctx = "%s %s N=%d L=%d" % (wavelet, mode, n, level)
                assert res.returncode == 0, ctx + ": " + res.stderr
                _compare(_parse_arrays(res.stdout), _wavedec(x, wavelet, mode, level), ctx)


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_wavedec_long_signal_matches_pywt(wavelet):
    _require_pywt()
    exe = _binary("dwt_coeffs")
    x, x_text = _long_signal()
    for mode in MODES:
        res = _run([exe, "--wavelet", wavelet, "--level", "8", "--mode", mode], x_text)
        ctx = "%s %s N=%d L=8" % (wavelet, mode, LONG_LENGTH)
        assert res.returncode == 0, ctx + ": " + res.stderr
        _compare(_parse_arrays(res.stdout), _wavedec(x, wavelet, mode, 8), ctx)


def _pywt_selected(x, wavelet, mode, level, keep, approx):
    coeffs = _wavedec(x, wavelet, mode, level)
    # coeffs = [cA_L, cD_L, ..., cD_1]; cD_j is at index L - j + 1.
    out = [c if (approx if i == 0 else (level - i + 1) in keep) else np.zeros_like(c)
           for i, c in enumerate(coeffs)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = pywt.waverec(out, wavelet, mode=mode)
    return rec[:len(x)]


KEEP_CASES = [
    (6, (3, 4, 5), False),  # paper Eq. 1
    (6, (1,), False),
    (6, (6,), True),
    (6, (), True),  # approximation only
    (6, (1, 2, 3, 4, 5, 6), True),  # everything: perfect reconstruction
    (8, (2, 7, 8), False),
]


@pytest.mark.parametrize("wavelet", WAVELETS)
def test_denoise_matches_pywt_waverec(wavelet):
    _require_pywt()
    exe = _binary("denoise")
    for n in [240, 257]:
        x = _signal(n, seed=1000 + n)
        x_text = _to_stdin(x)
        for mode in MODES:
            for level, keep, approx in KEEP_CASES:
                args = [exe, "--wavelet", wavelet, "--level", str(level), "--mode", mode]
                args += ["--keep", ",".join(str(j) for j in keep) if keep else "none"]
                if approx:
                    args.append("--approx")
                res = _run(args, x_text)
                assert res.returncode == 0, res.stderr
                got = np.array(res.stdout.split(), dtype=float)
                ref = _pywt_selected(x, wavelet, mode, level, set(keep), approx)
                ctx = "denoise %s %s N=%d L=%d keep=%s approx=%s" % (wavelet, mode, n, level,
                                                                     keep, approx)
                _compare([got], [ref], ctx)
                if keep == (1, 2, 3, 4, 5, 6) and approx:
                    assert float(np.max(np.abs(got - x))) < TOL, ctx + ": not perfect"


def test_denoise_long_signal_matches_pywt():
    _require_pywt()
    exe = _binary("denoise")
    x = _signal(LONG_LENGTH + 1, seed=777)  # odd length
    x_text = _to_stdin(x)
    for wavelet in ["coif4", "bior2.8", "coif5", "db5"]:
        for mode in MODES:
            res = _run([exe, "--wavelet", wavelet, "--level", "8", "--keep", "3,4,5",
                        "--mode", mode], x_text)
            assert res.returncode == 0, res.stderr
            got = np.array(res.stdout.split(), dtype=float)
            ref = _pywt_selected(x, wavelet, mode, 8, {3, 4, 5}, False)
            _compare([got], [ref], "denoise %s %s N=%d" % (wavelet, mode, x.size))


def test_denoise_output_format():
    exe = _binary("denoise")
    res = _run([exe, "--wavelet", "db5"], _to_stdin(_signal(64, seed=3)))
    assert res.returncode == 0, res.stderr
    lines = res.stdout.rstrip("\n").split("\n")
    assert len(lines) == 64
    for line in lines:
        v = float(line)
        assert math.isfinite(v)
        assert float("%.17g" % v) == v
        assert line == "%.17g" % v  # 17 significant digits, C printf formatting


GOOD_INPUT = _to_stdin(np.linspace(0.0, 1.0, 64))

BAD_CASES = [
    # (tool, args, stdin, text expected in stderr)
    ("denoise", ["--wavelet", "db99"], GOOD_INPUT, "db99"),
    ("denoise", ["--wavelet", "nosuch"], GOOD_INPUT, "nosuch"),
    ("denoise", [], GOOD_INPUT, "--wavelet"),
    ("denoise", ["--wavelet", "coif4", "--level", "0"], GOOD_INPUT, "level"),
    ("denoise", ["--wavelet", "coif4", "--level", "-2"], GOOD_INPUT, "level"),
    ("denoise", ["--wavelet", "coif4", "--level", "abc"], GOOD_INPUT, "level"),
    ("denoise", ["--wavelet", "coif4", "--level", "99"], GOOD_INPUT, "level"),
    ("denoise", ["--wavelet", "coif4", "--level"], GOOD_INPUT, "--level"),
    ("denoise", ["--wavelet", "coif4", "--keep", "3,x"], GOOD_INPUT, "--keep"),
    ("denoise", ["--wavelet", "coif4", "--keep", ""], GOOD_INPUT, "--keep"),
    ("denoise", ["--wavelet", "coif4", "--keep", "3,7"], GOOD_INPUT, "--keep"),
    ("denoise", ["--wavelet", "coif4", "--keep", "0"], GOOD_INPUT, "--keep"),
    ("denoise", ["--wavelet", "coif4", "--keep", "3,3"], GOOD_INPUT, "--keep"),
    ("denoise", ["--wavelet", "coif4", "--keep", "none"], GOOD_INPUT, "--keep"),
    ("denoise", ["--wavelet", "coif4", "--mode", "zero"], GOOD_INPUT, "zero"),
    ("denoise", ["--wavelet", "coif4", "--bogus"], GOOD_INPUT, "--bogus"),
    ("denoise", ["--wavelet", "coif4"], "1.0\nnan\n2.0\n", "nan"),
    ("denoise", ["--wavelet", "coif4"], "1.0\ninf\n", "inf"),
    ("denoise", ["--wavelet", "coif4"], "1.0\nabc\n", "abc"),
    ("denoise", ["--wavelet", "coif4"], "1.0\n2.0x\n", "2.0x"),
    ("denoise", ["--wavelet", "coif4"], "", "empty"),
    ("denoise", ["--wavelet", "coif4"], "\n  \n", "empty"),
    ("dwt_coeffs", ["--wavelet", "haar2"], GOOD_INPUT, "haar2"),
    ("dwt_coeffs", ["--wavelet", "db4", "--level", "0"], GOOD_INPUT, "level"),
    ("dwt_coeffs", ["--wavelet", "db4", "--mode", "smooth"], GOOD_INPUT, "smooth"),
    ("dwt_coeffs", ["--wavelet", "db4"], "1\nNaN\n", "NaN"),
    ("dwt_coeffs", ["--wavelet", "db4"], "", "empty"),
]


@pytest.mark.parametrize("tool,args,stdin,expected", BAD_CASES)
def test_cli_bad_arguments_exit_2(tool, args, stdin, expected):
    res = _run([_binary(tool)] + args, stdin)
    assert res.returncode == 2, (args, res.returncode, res.stdout, res.stderr)
    assert expected in res.stderr, res.stderr
    assert res.stdout == ""


@pytest.mark.parametrize("tool", ["denoise", "dwt_coeffs"])
def test_cli_help(tool):
    res = _run([_binary(tool), "--help"], "")
    assert res.returncode == 0
    assert "Usage" in res.stdout

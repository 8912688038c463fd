#!/usr/bin/python3
"""One-off generator of src/core/breathing/wavelet_filters.cpp from PyWavelets.

The wavelet filter coefficients are mathematical constants. Rather than typing
them in by hand, they are taken once from PyWavelets (``pywt.Wavelet(name)``,
attributes ``dec_lo``, ``dec_hi``, ``rec_lo``, ``rec_hi``) and printed with 17
significant digits, which round-trips IEEE-754 doubles exactly.

Usage (from the package root):

    /usr/bin/python3 scripts/dev/generate_wavelet_filters.py > src/core/breathing/wavelet_filters.cpp

The output is deterministic; re-running it with the same pywt version gives the
same file. Note that ``python3`` on PATH may be an interpreter without pywt, so
call /usr/bin/python3 explicitly.
"""

import sys

import pywt

# Order here is the order of pedicle_drilling::allWaveletNames().
FAMILIES = [
    ("kDaubechies", ["db%d" % k for k in range(1, 21)]),
    ("kSymlets", ["sym%d" % k for k in range(2, 21)]),
    ("kCoiflets", ["coif%d" % k for k in range(1, 6)]),
    ("kBiorthogonal", [
        "bior1.1", "bior1.3", "bior1.5", "bior2.2", "bior2.4", "bior2.6", "bior2.8",
        "bior3.1", "bior3.3", "bior3.5", "bior3.7", "bior3.9", "bior4.4", "bior5.5",
        "bior6.8"
    ]),
]

COMMAND = "/usr/bin/python3 scripts/dev/generate_wavelet_filters.py > src/core/breathing/wavelet_filters.cpp"


def ident(name):
    return "k" + name.replace(".", "_").capitalize()


def fmt_array(values):
    items = ["%.17g" % v for v in values]
    lines = []
    line = "   "
    for item in items:
        piece = " " + item + ","
        if len(line) + len(piece) > 98:
            lines.append(line)
            line = "   "
        line += piece
    lines.append(line)
    return "\n".join(lines)


def main():
    out = sys.stdout
    out.write("// GENERATED FILE - DO NOT EDIT BY HAND.\n")
    out.write("//\n")
    out.write("// Wavelet filter coefficients (mathematical constants) taken from PyWavelets %s\n"
              % pywt.__version__)
    out.write("// (Debian package python3-pywt), attributes dec_lo/dec_hi/rec_lo/rec_hi of\n")
    out.write("// pywt.Wavelet(name), printed with 17 significant digits "
              "(exact double round trip).\n")
    out.write("// Generated with:\n//   %s\n" % COMMAND)
    out.write("// from the package root. See scripts/dev/generate_wavelet_filters.py.\n\n")
    out.write("#include <cstddef>\n\n")
    out.write('#include "pedicle_drilling/core/breathing/wavelet.hpp"\n\n')
    out.write("namespace pedicle_drilling {\nnamespace detail {\nnamespace {\n\n")
    entries = []
    for family, names in FAMILIES:
        for name in names:
            w = pywt.Wavelet(name)
            filters = [w.dec_lo, w.dec_hi, w.rec_lo, w.rec_hi]
            length = len(w.dec_lo)
            assert all(len(f) == length for f in filters), name
            assert length % 2 == 0, name
            base = ident(name)
            for suffix, f in zip(["DecLo", "DecHi", "RecLo", "RecHi"], filters):
                out.write("// %s %s\n" % (name, suffix))
                out.write("constexpr double %s%s[%d] = {\n%s\n};\n" %
                          (base, suffix, length, fmt_array(f)))
            out.write("\n")
            entries.append((name, family, bool(w.orthogonal), length, base))
    out.write("constexpr RawWaveletFilters kTable[] = {\n")
    for name, family, orth, length, base in entries:
        out.write('    {"%s", WaveletFamily::%s, %s, %d,\n' %
                  (name, family, "true" if orth else "false", length))
        out.write('     %sDecLo, %sDecHi, %sRecLo, %sRecHi},\n' % (base, base, base, base))
    out.write("};\n\n")
    out.write("}  // namespace\n\n")
    out.write("const RawWaveletFilters* rawWaveletTable(std::size_t* count) {\n")
    out.write("  *count = sizeof(kTable) / sizeof(kTable[0]);\n")
    out.write("  return kTable;\n")
    out.write("}\n\n")
    out.write("}  // namespace detail\n}  // namespace pedicle_drilling\n")


if __name__ == "__main__":
    main()

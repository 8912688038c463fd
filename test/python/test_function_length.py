"""No function in src/ or include/ longer than about 120 lines: a long function is
split into named steps. The scan is lexical (comments and literals removed, braces matched): a
function body is a brace block whose head ends like a signature, nested lambdas and blocks count
to their function."""
import os
import re

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
LIMIT = 125  # lines, from the signature's opening brace to the closing one
CONTROL = re.compile(r'^\s*(if|for|while|switch|catch|do|else|try|return)\b')
SIGNATURE = re.compile(r'\)\s*(const\s*)?(noexcept\s*)?(override\s*)?(final\s*)?'
                       r'(->\s*[\w:<>,\s*&]+)?\s*(:\s*[^;{}]*)?$', re.S)


def strip(text):
    """The text with comments and string/char literals blanked, newlines kept."""
    out, i, n = [], 0, len(text)
    while i < n:
        if text.startswith('//', i):
            j = text.find('\n', i)
            i = n if j < 0 else j
        elif text.startswith('/*', i):
            j = text.find('*/', i + 2)
            j = n if j < 0 else j + 2
            out.append('\n' * text.count('\n', i, j))
            i = j
        elif text.startswith('R"(', i):
            j = text.find(')"', i + 3)
            j = n if j < 0 else j + 2
            out.append('""' + '\n' * text.count('\n', i, j))
            i = j
        elif text[i] in '"\'':
            quote, j = text[i], i + 1
            while j < n and text[j] != quote:
                j += 2 if text[j] == '\\' else 1
            out.append(quote * 2 + '\n' * text.count('\n', i, j))
            i = j + 1
        else:
            out.append(text[i])
            i += 1
    return ''.join(out)


def functions(path):
    """[(lines, first line, head)] of every function body in the file."""
    with open(path, encoding='utf-8') as handle:
        text = strip(handle.read())
    found, depth, head, line = [], 0, '', 1
    start = start_depth = name = None
    for ch in text:
        if ch == '\n':
            line += 1
        if ch == '{':
            h = head.strip()
            if (start is None and SIGNATURE.search(h) and not CONTROL.match(h)
                    and not re.match(r'^\s*(namespace|class|struct|enum|union)\b', h)
                    and '=' not in h.split('(')[0]):
                start, start_depth, name = line, depth, re.sub(r'\s+', ' ', h)[-80:]
            depth += 1
            head = ''
        elif ch == '}':
            depth -= 1
            head = ''
            if start is not None and depth == start_depth:
                found.append((line - start + 1, start, name))
                start = None
        elif ch == ';':
            head = ''
        else:
            head += ch
    return found


def test_the_scan_finds_a_long_function(tmp_path):
    source = tmp_path / 'long.cpp'
    source.write_text('namespace a {\nint f(int x) {\n' + '  x += 1;  // {\n' * 200 +
                      '  return x;\n}\nint g() { return 1; }\n}  // namespace a\n')
    lengths = sorted(n for n, _, _ in functions(str(source)))
    assert lengths == [1, 203], lengths


def test_no_function_over_the_limit():
    long = []
    for folder in ('src', 'include'):
        for directory, _, names in os.walk(os.path.join(ROOT, folder)):
            for name in names:
                if name.endswith(('.cpp', '.hpp', '.h')):
                    path = os.path.join(directory, name)
                    for lines, first, head in functions(path):
                        if lines > LIMIT:
                            long.append('%s:%d %d lines (%s)' % (os.path.relpath(path, ROOT),
                                                                first, lines, head))
    assert long == [], 'functions over %d lines:\n%s' % (LIMIT, '\n'.join(long))


# Python: no function over 80 lines in the package, the tools and the scripts.
PYTHON_LIMIT = 80
PYTHON_DIRS = ('src', 'scripts')


def python_functions(path):
    """(name, lines) of every function and method in a Python file."""
    import ast
    with open(path) as handle:
        tree = ast.parse(handle.read(), path)
    return [(node.name, node.end_lineno - node.lineno + 1) for node in ast.walk(tree)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))]


def test_the_python_scan_counts_from_the_def_to_the_last_line(tmp_path):
    path = tmp_path / 'module.py'
    path.write_text('def short():\n    return 1\n\n\nclass A:\n    def method(self):\n'
                    + '        x = 1\n' * 90 + '        return x\n')
    assert python_functions(str(path)) == [('short', 2), ('method', 92)]


def test_no_python_function_over_the_limit():
    long = []
    for top in PYTHON_DIRS:
        for folder, _, files in os.walk(os.path.join(ROOT, top)):
            for name in sorted(files):
                if not name.endswith('.py'):
                    continue
                path = os.path.join(folder, name)
                relative = os.path.relpath(path, ROOT)
                for function, lines in python_functions(path):
                    if lines > PYTHON_LIMIT:
                        long.append('%s: %s, %d lines' % (relative, function, lines))
    assert long == [], 'Python functions over %d lines:\n%s' % (PYTHON_LIMIT, '\n'.join(long))

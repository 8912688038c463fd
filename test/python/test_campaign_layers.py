"""The campaign package's layers (src/pd_campaign), read from its syntax trees, nothing imported:
no module over MODULE_LIMIT lines (a longer one is split by concern), no import of another
module's private name (a helper two modules share lives in one module, public there), and no
import cycle between its modules (the imports inside functions count: a late import hides a
cycle, it does not remove it)."""
import ast
import os

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..'))
SOURCE = os.path.join(ROOT, 'src')
PACKAGE = 'pd_campaign'
MODULE_LIMIT = 600  # lines


def modules(source=SOURCE, package=PACKAGE):
    """{dotted module name: path} of every module of the package, sub-packages included."""
    found = {}
    for folder, _, files in os.walk(os.path.join(source, package)):
        for name in sorted(files):
            if not name.endswith('.py'):
                continue
            path = os.path.join(folder, name)
            parts = os.path.relpath(path, source)[:-3].split(os.sep)
            if parts[-1] == '__init__':
                parts.pop()
            found['.'.join(parts)] = path
    return found


def _absolute(module, is_package, level, name):
    """The dotted name an import statement of `module` names (level: its leading dots)."""
    if level == 0:
        return name or ''
    base = module.split('.') if is_package else module.split('.')[:-1]
    base = base[:len(base) - (level - 1)]
    return '.'.join(base + ([name] if name else []))


def imports(name, path, known):
    """([(line, imported module)], [(line, text)] of private names of other modules it uses)."""
    with open(path) as handle:
        tree = ast.parse(handle.read(), path)
    is_package = path.endswith('__init__.py')
    edges, private, bound = [], [], {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in known:
                    edges.append((node.lineno, alias.name))
                    if alias.asname:
                        bound[alias.asname] = alias.name
        elif isinstance(node, ast.ImportFrom):
            target = _absolute(name, is_package, node.level, node.module)
            for alias in node.names:
                full = target + '.' + alias.name
                if full in known:  # a module of the package: `from . import report`
                    edges.append((node.lineno, full))
                    bound[alias.asname or alias.name] = full
                elif target in known:
                    edges.append((node.lineno, target))
                    if alias.name.startswith('_') and target != name:
                        private.append((node.lineno, 'from %s import %s' % (target, alias.name)))
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in bound and node.attr.startswith('_')
                and not node.attr.startswith('__') and bound[node.value.id] != name):
            private.append((node.lineno, '%s.%s' % (bound[node.value.id], node.attr)))
    return edges, private


def graph(known):
    """{module: set of the package's modules it imports}, and the private-name uses."""
    edges, private = {}, []
    for name, path in known.items():
        found, uses = imports(name, path, known)
        edges[name] = {target for _, target in found if target != name}
        private += ['%s:%d %s' % (os.path.relpath(path, ROOT), line, text)
                    for line, text in sorted(set(uses))]
    return edges, private


def cycles(edges):
    """The import cycles, each as the list of its modules (Tarjan's strongly connected
    components of more than one module)."""
    index, low, stack, on_stack, found, counter = {}, {}, [], set(), [], [0]

    def visit(node):
        index[node] = low[node] = counter[0]
        counter[0] += 1
        stack.append(node)
        on_stack.add(node)
        for nxt in sorted(edges.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                component.append(top)
                if top == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return found


def _package(tmp_path, files):
    root = tmp_path / 'src'
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return modules(str(root), 'pkg')


def test_the_scan_finds_private_imports_and_cycles(tmp_path):
    known = _package(tmp_path, {
        'pkg/__init__.py': '',
        'pkg/a.py': 'from . import b\nfrom .c import _hidden\n\n\ndef f():\n    return b._x\n',
        'pkg/b.py': 'def g():\n    from pkg import a\n    return a\n',
        'pkg/c.py': '_hidden = 1\n',
        'pkg/sub/__init__.py': 'from .d import public\n',
        'pkg/sub/d.py': 'from .. import c\npublic = c\n'})
    edges, private = graph(known)
    assert edges['pkg.a'] == {'pkg.b', 'pkg.c'}
    assert edges['pkg.sub'] == {'pkg.sub.d'} and edges['pkg.sub.d'] == {'pkg.c'}
    assert sorted(text.split(' ', 1)[1] for text in private) == [
        'from pkg.c import _hidden', 'pkg.b._x']
    assert cycles(edges) == [['pkg.a', 'pkg.b']]


def test_no_module_over_the_limit():
    long = []
    for name, path in sorted(modules().items()):
        with open(path) as handle:
            lines = sum(1 for _ in handle)
        if lines > MODULE_LIMIT:
            long.append('%s: %d lines' % (os.path.relpath(path, ROOT), lines))
    assert long == [], 'modules over %d lines (split them by concern):\n%s' % (
        MODULE_LIMIT, '\n'.join(long))


def test_no_import_of_another_modules_private_name():
    _, private = graph(modules())
    assert private == [], ('private names used outside their module (make the shared helper '
                           'public in one module):\n%s' % '\n'.join(private))


def test_no_import_cycle():
    found = cycles(graph(modules())[0])
    assert found == [], 'import cycles between modules of %s:\n%s' % (
        PACKAGE, '\n'.join(' <-> '.join(cycle) for cycle in found))

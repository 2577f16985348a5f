"""
The ROS 2 linters as tests, as demo_nodes_py runs them, and the docstring rule of the package.

``ament_flake8`` runs with its default configuration (line length 99, single quotes, google
import order, the plugins its ROS package depends on); ``ament_pep257`` with the ament
convention (summary on the second line of a multi-line docstring).  Both check the package,
the tests and setup.py.  The docstring rule: every public module, class and function of the
package has a docstring, and a function with arguments documents them in a numpydoc
``Parameters`` section (a class: its constructor arguments).
"""
import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PATHS = [str(REPO / 'strapdown_ros'), str(REPO / 'test'), str(REPO / 'setup.py')]


@pytest.mark.linter
def test_flake8(tmp_path, monkeypatch):
    """
    Run ament_flake8: no code style errors or warnings.

    ament_flake8 walks its working directory for AMENT_IGNORE markers, the virtual environment
    included; from an empty directory it checks the same absolute paths in 2/3 of the time.
    """
    main_with_errors = pytest.importorskip('ament_flake8.main').main_with_errors
    monkeypatch.chdir(tmp_path)
    rc, errors = main_with_errors(argv=PATHS)
    assert rc == 0, f'Found {len(errors)} code style errors / warnings:\n' + '\n'.join(errors)


@pytest.mark.linter
def test_pep257():
    """Run ament_pep257: no docstring style errors."""
    main = pytest.importorskip('ament_pep257.main').main
    rc = main(argv=PATHS[:2])
    assert rc == 0, 'Found docstring style errors (listed above)'


def missing_docstrings(path):
    """
    Return the public definitions of a module that break the docstring rule.

    Parameters
    ----------
    path : pathlib.Path
        A module of the package.

    Returns
    -------
    list of str
        ``line: name: what is missing``, one per definition.

    """
    tree = ast.parse(path.read_text(encoding='utf-8'))
    out = [] if ast.get_docstring(tree) else ['1: module docstring']

    def visit(body, prefix):
        for node in body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith('_'):
                doc = ast.get_docstring(node) or ''
                init = [m for m in node.body
                        if isinstance(m, ast.FunctionDef) and m.name == '__init__']
                if not doc:
                    out.append(f'{node.lineno}: {prefix}{node.name}: no docstring')
                elif init and len(init[0].args.args) > 1 and 'Parameters\n---' not in doc:
                    out.append(f'{node.lineno}: {prefix}{node.name}: constructor arguments '
                               'without a Parameters section')
                visit(node.body, f'{prefix}{node.name}.')
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                    and not node.name.startswith('_'):
                doc = ast.get_docstring(node) or ''
                args = [a.arg for a in node.args.args + node.args.kwonlyargs
                        if a.arg not in ('self', 'cls')]
                args += [a.arg for a in (node.args.vararg, node.args.kwarg) if a]
                if not doc:
                    out.append(f'{node.lineno}: {prefix}{node.name}: no docstring')
                elif args and 'Parameters\n---' not in doc:
                    out.append(f'{node.lineno}: {prefix}{node.name}: no Parameters section')

    visit(tree.body, '')
    return out


def test_public_definitions_have_numpydoc_docstrings():
    """Every public definition of the package is documented, its arguments in numpydoc."""
    modules = sorted((REPO / 'strapdown_ros').rglob('*.py'))
    offenders = [f'{p.relative_to(REPO)}:{m}' for p in modules for m in missing_docstrings(p)]
    assert not offenders, f'{len(offenders)} missing:\n' + '\n'.join(offenders)

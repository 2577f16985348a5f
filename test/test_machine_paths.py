"""
No path of one particular machine in the repository's code, tests, scripts, docs or config.

Data is found through an environment variable (``STRAPDOWN_REALDATA``) or shipped in
``test/data/``; scratch files go to pytest's ``tmp_path`` or ``tempfile``.  The rule is that of
the project's before-stop check (:data:`PATTERN`):

* anything below ``/work`` or ``/home/<user>`` names a folder of one machine;
* a path *below* a folder of ``/tmp`` (``/tmp/<name>/…``) names a folder someone made there;
* one name directly under ``/tmp`` — ``/tmp/NAME``, or a documented example such as
  ``/tmp/tstick08`` in a command that itself creates it — is a scratch name any machine has,
  and is allowed.

``doc/results/`` is left out: it holds what commands printed, recorded as printed.
"""
from pathlib import Path
import re

ROOT = Path(__file__).resolve().parents[1]
#: where the rule applies (files and folders, from the repository root)
SCOPE = ('strapdown_ros', 'test', 'scripts', 'doc', 'config', '.ci', 'README.md', 'setup.py',
         'setup.cfg', 'pyproject.toml', 'package.xml', 'CHANGELOG.rst')
EXCLUDED = ('doc/results',)
_W = 'wor' + 'k'                  # spelled apart so that this file passes its own test
PATTERN = re.compile(rf'(/{_W}/|/home/[a-z]|/tmp/[A-Za-z0-9_.-]+/)')


def _files():
    for name in SCOPE:
        top = ROOT / name
        paths = [top] if top.is_file() else sorted(p for p in top.rglob('*') if p.is_file())
        for p in paths:
            rel = p.relative_to(ROOT).as_posix()
            if '__pycache__' in p.parts or any(rel.startswith(e + '/') for e in EXCLUDED):
                continue
            yield rel, p


def test_pattern_matches_what_it_should():
    bad = [f'/{_W}/main', '/' + 'home/alice/data', '/tmp' + '/probe_venv/bin/python',
           '/tmp' + '/x/hour']
    good = ['/tmp/tstick08', '/tmp/NAME', '$TMPDIR/x/y', '/tmp/boresight.json', 'homework/',
            '/opt/ros/jazzy']
    assert all(PATTERN.search(s) for s in bad)
    assert not any(PATTERN.search(s) for s in good)


def test_no_path_of_one_machine_in_the_repository():
    hits, read = [], 0
    for rel, p in _files():
        try:
            text = p.read_text(encoding='utf-8')
        except UnicodeDecodeError:                    # binary (PNG, MCAP): no paths to read
            continue
        read += 1
        for k, line in enumerate(text.splitlines(), 1):
            m = PATTERN.search(line)
            if m:
                hits.append(f'{rel}:{k}: {m.group(0)}')
    assert read > 100                                 # the scope was really read
    assert not hits, 'paths of one machine (use an environment variable, a shipped fixture, ' \
        'tmp_path, or /tmp/NAME in a doc example):\n' + '\n'.join(hits)

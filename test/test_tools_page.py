"""doc/tools.md lists every console script of setup.py: in its table of nodes, or by a synopsis."""
from pathlib import Path
import re

ROOT = Path(__file__).resolve().parents[1]


def _scripts() -> list[str]:
    setup = (ROOT / 'setup.py').read_text(encoding='utf-8')
    block = setup[setup.index("'console_scripts'"):]
    return re.findall(r"'(\w+)\s*=\s*strapdown_ros\.", block[:block.index(']')])


def test_every_console_script_is_on_the_tools_page():
    page = (ROOT / 'doc' / 'tools.md').read_text(encoding='utf-8')
    rows = set(re.findall(r'^\| `(\w+)` \|', page, re.M))            # the table of nodes
    synopses = set(re.findall(r'^ {4}(\w+) \[-h\]', page, re.M))    # a --help usage line
    scripts = _scripts()
    assert len(scripts) > 20
    missing = [s for s in scripts if s not in rows | synopses]
    assert not missing, f'doc/tools.md lacks {missing}'
    stale = sorted((rows | synopses) - set(scripts))
    assert not stale, f'doc/tools.md lists what setup.py does not install: {stale}'

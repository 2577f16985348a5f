"""The fleet's manifest (CSV or folder), its cache key, and its one-line errors."""
from datetime import datetime, timedelta, timezone

import pytest

from strapdown_ros.fleet.analysis import FleetOptions
from strapdown_ros.fleet.cache import content_hash
from strapdown_ros.fleet.manifest import parse_time, read_manifest


def test_iso_times_in_every_accepted_form():
    want = datetime(2024, 5, 1, 12, 30, 5, tzinfo=timezone.utc)
    for text in ('2024-05-01T12:30:05Z', '20240501T123005Z', '2024-05-01T12-30-05Z',
                 '2024-05-01T12:30:05', '2024-05-01T14:30:05+02:00'):
        assert parse_time(text) == want, text
    assert parse_time('2024-05-01T12:30:05.25Z') == want + timedelta(microseconds=250000)
    assert parse_time('2024-05-01') == datetime(2024, 5, 1, tzinfo=timezone.utc)
    with pytest.raises(ValueError, match='ISO 8601'):
        parse_time('1 May 2024')


def test_csv_paths_are_relative_to_the_manifest(tmp_path):
    (tmp_path / 'u1').mkdir()
    (tmp_path / 'u1' / 'a.mcap').write_bytes(b'x')
    (tmp_path / 'm.yaml').write_text('{}')
    m = tmp_path / 'fleet.csv'
    m.write_text('unit,recording,start_time,model\n'
                 'u1,u1/a.mcap,2024-05-02T00:00:00Z,m.yaml\n'
                 'u0,/abs/b,2024-05-01T00:00:00Z,\n')
    entries, skipped = read_manifest(m)
    assert skipped == 0 and [e.unit for e in entries] == ['u0', 'u1']
    assert entries[1].path == str((tmp_path / 'u1' / 'a.mcap').resolve())
    assert entries[1].model == str((tmp_path / 'm.yaml').resolve()) and entries[0].model is None
    assert entries[0].path == '/abs/b' and entries[1].start_iso == '2024-05-02T00:00:00Z'


@pytest.mark.parametrize('text, what', [
    ('unit,recording,model\nu,r,m\n', 'no column start_time'),
    ('unit,recording,start_time,model\nu,r,yesterday,\n', 'line 2: start_time'),
    ('unit,recording,start_time,model\nu,r,2024-05-01T00:00:00Z,\nv,r,2024-05-01T00:00:00Z,\n',
     'named twice'),
])
def test_bad_manifests_are_one_line_errors(tmp_path, text, what):
    m = tmp_path / 'fleet.csv'
    m.write_text(text)
    with pytest.raises(ValueError, match=what) as err:
        read_manifest(m)
    assert '\n' not in str(err.value)


def test_folder_layout_and_its_naming_pattern(tmp_path):
    for unit, names in (('u1', ['20240501T000000Z', '2024-05-02T00-00-00Z_bench.mcap', 'notes']),
                        ('u2', ['20240503T060000Z.db3'])):
        (tmp_path / unit).mkdir()
        for n in names:
            if n.endswith(('.mcap', '.db3')) or n == 'notes':
                (tmp_path / unit / n).write_bytes(b'x')
            else:
                (tmp_path / unit / n).mkdir()
    (tmp_path / 'model.yaml').write_text('{}')
    (tmp_path / 'u2' / 'model.yaml').write_text('{}')
    entries, skipped = read_manifest(tmp_path)
    assert skipped == 1                                      # 'notes'
    assert [(e.unit, e.start_iso) for e in entries] == [
        ('u1', '2024-05-01T00:00:00Z'), ('u1', '2024-05-02T00:00:00Z'),
        ('u2', '2024-05-03T06:00:00Z')]
    assert entries[0].model.endswith('model.yaml') and '/u2/' in entries[2].model


def test_content_hash_follows_the_bytes_the_model_and_the_options(tmp_path):
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('a')
    (bag / 'b_0.mcap').write_bytes(b'0123')
    model = tmp_path / 'm.yaml'
    model.write_text('{}')
    key = FleetOptions().key()
    h = content_hash(str(bag), str(model), key)
    assert h == content_hash(str(bag), str(model), key)
    (bag / 'b_0.mcap').write_bytes(b'0124')
    h2 = content_hash(str(bag), str(model), key)
    model.write_text('{"a": 1}')
    h3 = content_hash(str(bag), str(model), key)
    h4 = content_hash(str(bag), str(model), FleetOptions(alpha=0.05).key())
    assert len({h, h2, h3, h4}) == 4
    assert FleetOptions(memory_mib=512).key() == key         # a budget changes no result

"""
Bounded work for any input: hostile and broken files end as one line, in bounded memory.

Each hostile file reproduces a problem of issue 24 (a 32 KB MCAP whose zstd chunk claims
1 GiB, a .npz of int8 zeros that widens to float64, a metadata.yaml of nested aliases, a
folder of self-referencing links, a CSV header cell over 131072 characters, `../` in
relative_file_paths, a file whose first bytes an error used to quote). The fuzz test runs
`validate` on every hostile file and on seeded mutations of a valid bag (MCAP, uncompressed
and zstd, one whose chunks carry no checksum, so that a mutated chunk reaches the walk that
decodes pose messages in blocks, and one of a driver's arrays of named bodies), metadata.yaml,
Vicon CSV, C3D, Qualisys TSV (3D and 6DOF), TUM, EuRoC and headed CSV table and .npz file,
in one child process, and checks that each ends in exit 0 or one `error:` line with exit 1,
without a traceback, and that the child's peak memory stays below MEMORY_BOUND_MB.

Every file is written by a real writer (the package's bag writer, mcap's Writer, ezc3d,
numpy); a hostile one is a valid file with bytes patched afterwards, as each case says.
"""
from __future__ import annotations

from collections.abc import Callable
import json
import os
from pathlib import Path
import random
import struct
import subprocess
import sys
import time
import zipfile

from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from driver_bags import named_pose_bag
from mocap_helpers import body_rotations, write_c3d, write_vicon_csv
import octoroach_model as om
from octoroach_model.errors import BagError
from octoroach_model.recordings import (
    bag_files,
    BagReader,
    expand_sources,
    read_runs,
    save_dataset,
    write_paths_bag,
)
from octoroach_model.recordings.bagio.repair import repair_bag
from trajectory_writers import (
    planar_pose,
    write_euroc,
    write_pose_csv,
    write_qtm_3d,
    write_qtm_6d,
    write_tum,
)

REPO = Path(__file__).resolve().parents[1]
SEED = int(os.environ.get('OCTOROACH_TEST_SEED', '0'))
# the child reading every case: its imports take about 100 MB; the hostile files would take
# 1-10 GB without the limits
MEMORY_BOUND_MB = 400
MUTANTS_PER_SEED = 20
GIB = 1 << 30


# -- files ----------------------------------------------------------------------------------

def standard_bag(directory: Path, runs: int = 3) -> Path:
    """Write a bag as `simulate` writes it: metadata.yaml and one uncompressed MCAP file."""
    bag = directory / 'bag'
    write_paths_bag(bag, om.simulate(runs, seed=1, cycles=2))
    return bag


def zstd_mcap(directory: Path, bag: Path, compression: CompressionType = CompressionType.ZSTD,
              name: str = 'zstd.mcap', crcs: bool = True,
              log_time: Callable[[int, int], int] | None = None) -> Path:
    """
    Copy the bag's messages into one .mcap file written by mcap's Writer (zstd chunks).

    `log_time(number, log_time_ns)` gives the k-th message's log time (default: kept).
    """
    reader = BagReader(bag)
    reader.topics()
    path = directory / name
    with path.open('wb') as stream:
        writer = Writer(stream, compression=compression, chunk_size=4096, enable_crcs=crcs)
        writer.start(profile='ros2', library='test')
        channels = {}
        for index, channel in enumerate(reader.channels):
            schema = writer.register_schema(channel.msgtype, channel.schema_encoding,
                                            channel.schema_data)
            channels[index] = writer.register_channel(channel.topic, channel.message_encoding,
                                                      schema, channel.metadata)
        for number, message in enumerate(reader.messages()):
            logged = message.log_time_ns if log_time is None else log_time(
                number, message.log_time_ns)
            writer.add_message(channels[message.channel], logged, message.data,
                               message.publish_time_ns)
        writer.finish()
    return path


def chunk_offsets(path: Path) -> list[int]:
    """Byte offsets of the chunk records of an MCAP file (mcap's StreamReader)."""
    offsets = []
    with path.open('rb') as stream:
        records = StreamReader(stream, emit_chunks=True).records
        position = stream.tell()
        for record in records:
            if isinstance(record, Chunk):
                offsets.append(position)
            position = stream.tell()
    return offsets


def chunk_claiming(directory: Path, bag: Path, claimed: int) -> Path:
    """
    Write the zstd file with its first chunk claiming `claimed` bytes decompressed.

    Patched: the chunk record's uncompressed_size, a uint64 after its opcode (1 byte), record
    length (8) and message start and end times (8 + 8).
    """
    source = zstd_mcap(directory, bag)
    data = bytearray(source.read_bytes())
    offset = chunk_offsets(source)[0] + 1 + 8 + 16
    data[offset:offset + 8] = struct.pack('<Q', claimed)
    path = directory / 'claims_a_gibibyte.mcap'
    path.write_bytes(bytes(data))
    return path


def int8_bomb(directory: Path, runs: int = 33_334, samples: int = 1000) -> Path:
    """
    Write a data set whose poses are int8 zeros, deflated: 100 MB of int8, 800 MB as float64.

    Written with numpy's public .npy header writer into a zip member, the zeros streamed in
    pieces (an .npz is a zip of .npy files, as np.savez_compressed writes it).
    """
    path = directory / 'int8_bomb.npz'
    t = np.arange(samples) / 50.0
    info = np.array(json.dumps({'format': 'octoroach_model.dataset', 'format_version': 1}))
    with zipfile.ZipFile(path, 'w', compression=zipfile.ZIP_DEFLATED) as archive:
        for name, array in (('t', t), ('info_json', info)):
            with archive.open(f'{name}.npy', 'w') as stream:
                np.lib.format.write_array(stream, array)
        with archive.open('poses.npy', 'w', force_zip64=True) as stream:
            np.lib.format.write_array_header_1_0(stream, {
                'descr': '|i1', 'fortran_order': False, 'shape': (runs, samples, 3)})
            piece = bytes(1 << 20)
            left = runs * samples * 3
            while left:
                stream.write(piece[:min(left, len(piece))])
                left -= min(left, len(piece))
    return path


def alias_bomb(directory: Path, bag: Path) -> Path:
    """Copy the bag with a 'billion laughs' metadata.yaml (nine levels of nine aliases)."""
    target = directory / 'laughs'
    target.mkdir()
    for file in bag.iterdir():
        (target / file.name).write_bytes(file.read_bytes())
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for level in range(1, 10):
        lines.append(f'a{level}: &a{level} [' + ', '.join([f'*a{level - 1}'] * 9) + ']')
    lines.append('rosbag2_bagfile_information: {version: 9, storage_identifier: mcap, '
                 'relative_file_paths: [*a9]}')
    (target / 'metadata.yaml').write_text('\n'.join(lines) + '\n')
    return target


def link_loop(directory: Path) -> Path:
    """Make a folder holding two links to itself (and nothing to read)."""
    folder = directory / 'loop'
    folder.mkdir()
    (folder / 'again').symlink_to('.')
    (folder / 'and_again').symlink_to('..' + os.sep + 'loop')
    return folder


def long_csv_cell(directory: Path) -> Path:
    """Write a Vicon CSV export whose names line holds one cell of 200 000 characters."""
    path = directory / 'long_cell.csv'
    path.write_text('Objects\r\n100\r\n,,' + 'x' * 200_000 + '\r\n'
                    'Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ\r\n,,deg,deg,deg,mm,mm,mm\r\n'
                    '1,0,0,0,0,0,0,0\r\n')
    return path


def secret_file(directory: Path) -> Path:
    """Write a text file with an MCAP name whose first bytes must never reach an error message."""
    path = directory / 'shadow.mcap'
    path.write_text('root:*:20000:0:99999:7:::\n')
    return path


def valid_seeds(directory: Path) -> dict[str, Path]:
    """One valid file of each kind the readers take, small."""
    bag = standard_bag(directory)
    paths = om.simulate(3, seed=2, cycles=2)
    frames = np.arange(1, len(paths.t) + 1)
    poses = paths.poses[0]
    positions = np.column_stack([poses[:, 0], poses[:, 1], np.zeros(len(poses))])
    csv_path = write_vicon_csv(directory / 'trial.csv', frames, {'hz': 50}, {
        'octo': (positions, body_rotations(poses[:, 2]), np.ones(len(poses), bool))})
    layout = {'A': (0.02, 0.0, 0.0), 'B': (-0.01, 0.01, 0.0), 'C': (-0.01, -0.01, 0.0)}
    rotation = Rotation.from_euler('z', poses[:, 2, None])
    markers = {name: rotation.apply(np.asarray(offset)) + positions
               for name, offset in layout.items()}
    c3d_path = write_c3d(directory / 'trial.c3d', 50.0, markers)
    stamps = 10**18 + np.round(paths.t * 1e9).astype(np.int64)
    where, rotations = planar_pose(poses)
    tracked = np.ones(len(poses), bool)
    named = named_pose_bag(directory / 'named', om.simulate(2, seed=3, cycles=2))
    # chunks without checksums: a mutation inside one reaches the pose blocks' walk
    unchecked = zstd_mcap(directory, bag, CompressionType.NONE, 'unchecked.mcap', crcs=False)
    return {'bag': bag, 'mcap': next(bag.glob('*.mcap')), 'zstd': zstd_mcap(directory, bag),
            'unchecked': unchecked,
            'metadata': bag / 'metadata.yaml', 'csv': csv_path, 'c3d': c3d_path,
            'npz': save_dataset(directory / 'runs.npz', paths),
            'tsv6d': write_qtm_6d(directory / 'trial_6d.tsv', 50.0,
                                  {'robot': (where, rotations, tracked)}),
            'tsv3d': write_qtm_3d(directory / 'trial.tsv', 50.0, markers),
            'tum': write_tum(directory / 'groundtruth.txt', stamps, where, rotations),
            'euroc': write_euroc(directory / 'data.csv', stamps, where, rotations),
            'table': write_pose_csv(directory / 'poses.csv', ['t', 'x', 'y', 'yaw'], [
                [f'{t:.3f}', f'{x:.6f}', f'{y:.6f}', f'{h:.6f}']
                for t, (x, y, h) in zip(paths.t, poses)]),
            'named': next(named.glob('*.mcap'))}


def mutate(data: bytes, rng: random.Random) -> bytes:
    """One seeded mutation: flipped bytes, a cut, a repeated or removed span, a huge field."""
    if not data:
        return data
    out = bytearray(data)
    kind = rng.randrange(5)
    if kind == 0:
        for _ in range(rng.randint(1, 8)):
            out[rng.randrange(len(out))] = rng.randrange(256)
    elif kind == 1:
        out = out[:rng.randrange(len(out))]
    elif kind == 2:
        start = rng.randrange(len(out))
        span = out[start:start + rng.randint(1, 512)]
        out[start:start] = span * rng.randint(1, 4)
    elif kind == 3:
        start = rng.randrange(len(out))
        del out[start:start + rng.randint(1, 256)]
    else:
        start = rng.randrange(max(1, len(out) - 8))
        out[start:start + 8] = struct.pack('<Q', rng.choice([GIB, 1 << 40, 2 ** 64 - 1]))
    return bytes(out)


def mutants(seeds: dict[str, Path], directory: Path, rng: random.Random) -> list[Path]:
    """Seeded mutations of every seed file; a bag's mutated file stays inside a bag copy."""
    made = []
    for kind, seed in seeds.items():
        if kind == 'bag':
            continue
        for number in range(MUTANTS_PER_SEED):
            if kind == 'metadata':
                bag = directory / f'meta_{number}'
                bag.mkdir()
                for file in seed.parent.iterdir():
                    (bag / file.name).write_bytes(file.read_bytes())
                target = bag / 'metadata.yaml'
                target.write_bytes(mutate(seed.read_bytes(), rng))
                made.append(bag)
                continue
            target = directory / f'{kind}_{number}{seed.suffix}'
            target.write_bytes(mutate(seed.read_bytes(), rng))
            made.append(target)
    return made


# -- the child that reads every case --------------------------------------------------------

CHILD = r"""
import contextlib, io, json, resource, sys, time, traceback
from octoroach_model.commands import run_command

def peak_mb():
    # VmHWM is this process's own peak; ru_maxrss also holds the peak of the process that
    # started it (the kernel carries it across exec): an xdist worker that had run the
    # diagnosis tests made every case read 450 MB
    try:
        with open('/proc/self/status', encoding='ascii') as status:
            for line in status:
                if line.startswith('VmHWM:'):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

results = []
for path in json.loads(sys.argv[1]):
    err = io.StringIO()
    started = time.monotonic()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = run_command('validate', [path])
    except BaseException:
        code, err = None, io.StringIO(traceback.format_exc())
    results.append({'path': path, 'code': code, 'stderr': err.getvalue(),
                    'seconds': time.monotonic() - started,
                    'peak_mb': peak_mb()})
print(json.dumps(results))
"""


def read_in_child(paths: list[Path]) -> list[dict]:
    result = subprocess.run([sys.executable, '-c', CHILD, json.dumps([str(p) for p in paths])],
                            cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def check_one_line(case: dict) -> str:
    """
    Check that the case ended in exit 0, or in one `error:` line and exit 1, untraced.

    `note:` lines (what a user must see of the data, e.g. an up axis that looks wrong) and
    progress lines may come before the error; the error itself is one line.
    """
    where = (f'OCTOROACH_TEST_SEED={SEED} {case["path"]}: exit {case["code"]}\n'
             f'{case["stderr"]}')
    assert 'Traceback' not in case['stderr'], where
    if case['code'] == 0:
        return ''
    lines = [line for line in case['stderr'].splitlines()
             if line.strip() and not line.startswith(('note: ', '['))]
    assert case['code'] == 1 and len(lines) == 1 and lines[0].startswith('error: '), where
    return lines[0]


# -- tests ----------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def hostile(tmp_path_factory) -> dict[str, Path]:
    directory = tmp_path_factory.mktemp('hostile')
    (directory / 'base').mkdir()
    bag = standard_bag(directory / 'base')
    return {'chunk': chunk_claiming(directory, bag, GIB), 'npz': int8_bomb(directory),
            'yaml': alias_bomb(directory, bag), 'loop': link_loop(directory),
            'csv': long_csv_cell(directory), 'secret': secret_file(directory)}


def test_hostile_and_mutated_files_end_as_one_line_in_bounded_memory(hostile, tmp_path):
    seeds = valid_seeds(tmp_path)
    (tmp_path / 'mutants').mkdir()
    cases = [*hostile.values(), *mutants(seeds, tmp_path / 'mutants', random.Random(SEED))]
    results = read_in_child(cases)

    by_path = {case['path']: case for case in results}
    for case in results:
        check_one_line(case)
        assert case['seconds'] < 30, case
    peak = max(case['peak_mb'] for case in results)
    assert peak < MEMORY_BOUND_MB, [(c['path'], c['peak_mb']) for c in results]
    said = {name: check_one_line(by_path[str(path)]) for name, path in hostile.items()}
    assert 'validate' in said['chunk']         # read past the refused chunk, then too few runs
    assert 'as float64, above the limit' in said['npz'], said['npz']
    assert 'no input in this directory' in said['loop'], said['loop']
    assert '131072 characters' in said['csv'] and 'xxx' not in said['csv'], said['csv']
    assert 'root:*' not in said['secret'] and 'not an MCAP file' in said['secret']


def test_a_message_logged_past_2262_is_skipped_with_a_note(tmp_path):
    # a log time is a uint64 in MCAP; past int64 nanoseconds no clock reaches it (a fuzzed
    # file once ended in OverflowError in the message-by-message reader)
    path = zstd_mcap(tmp_path, standard_bag(tmp_path), name='late.mcap', log_time=lambda
                     number, logged: (1 << 64) - 1 - number if number % 50 == 7 else logged)
    runs = read_runs([path])
    assert len(runs) == 3
    assert any('log time past the year 2262 skipped' in note for note in runs.notes), runs.notes


def test_a_chunk_over_the_limit_is_skipped_with_a_note_naming_the_limit(hostile):
    notes: list[str] = []
    reader = BagReader(hostile['chunk'], notes)
    assert list(reader.messages()) == [] or notes
    assert any('claims 1 GiB decompressed, above the limit of 64 MiB' in n for n in notes), notes


def test_yaml_aliases_in_metadata_are_refused_at_once(hostile):
    started = time.monotonic()
    files = bag_files(hostile['yaml'])
    assert time.monotonic() - started < 2
    assert any('YAML aliases are not accepted' in note for note in files.notes), files.notes
    assert [path.name for path in files.files] == ['bag_0.mcap']   # read directly


def test_a_folder_of_links_to_itself_is_searched_once(hostile):
    inside = hostile['loop'] / 'data.npz'
    save_dataset(inside, om.simulate(2, seed=1, cycles=2))
    try:
        assert expand_sources([hostile['loop']], suffixes=('.npz',)) == [inside]
    finally:
        inside.unlink()


def test_the_same_input_given_twice_is_refused(tmp_path):
    data = save_dataset(tmp_path / 'runs.npz', om.simulate(2, seed=1, cycles=2))
    with pytest.raises(BagError, match='given twice'):
        expand_sources([data, tmp_path], suffixes=('.npz',))
    with pytest.raises(BagError, match='given twice'):
        om.load_measured([data, str(data)])


def test_the_same_runs_under_two_names_are_said(tmp_path):
    """A bag and its copy doubled every run in silence (1001 runs, "gain 108 %")."""
    bag = standard_bag(tmp_path)
    copy = tmp_path / 'copy'
    copy.mkdir()
    for file in bag.iterdir():
        (copy / file.name.replace('bag', 'copy')).write_bytes(file.read_bytes())
    metadata = copy / 'metadata.yaml'
    metadata.write_text(metadata.read_text().replace('bag_0.mcap', 'copy_0.mcap'))
    assert not [n for n in om.load_measured([bag]).info['notes'] if 'same samples' in n]
    notes = om.load_measured([bag, copy]).info['notes']
    assert [n for n in notes if n.startswith('3 of 6 runs hold the same samples')], notes
    result = subprocess.run([sys.executable, '-m', 'octoroach_model', 'validate', str(bag),
                             str(copy)], cwd=REPO, capture_output=True, text=True)
    assert 'note: 3 of 6 runs hold the same samples' in result.stderr, result.stderr


def test_repair_never_leaves_the_bag_directory(tmp_path):
    bag = standard_bag(tmp_path)
    victim = tmp_path / 'victim.mcap'
    victim.write_bytes((bag / 'bag_0.mcap').read_bytes()[:-200])     # cut: "needs repair"
    metadata = bag / 'metadata.yaml'
    metadata.write_text(metadata.read_text().replace('- bag_0.mcap', '- ../victim.mcap'))
    before = victim.read_bytes()
    with pytest.raises(BagError, match='outside the bag directory'):
        repair_bag(bag)
    assert victim.read_bytes() == before and not (tmp_path / 'victim.mcap.damaged').exists()


def test_a_summary_reader_still_opens_the_zstd_seed(tmp_path):
    """The seed of the zstd mutants is a valid file (so its mutants test the reader)."""
    bag = standard_bag(tmp_path)
    path = zstd_mcap(tmp_path, bag)
    with path.open('rb') as stream:
        assert make_reader(stream).get_summary().statistics.message_count > 0
    assert len(chunk_offsets(path)) > 1

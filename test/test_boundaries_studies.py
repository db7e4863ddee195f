"""
Studies as their users deploy them: a private local cluster, TLS to a remote one, one writer.

Each test reproduces a problem of issue 24: the local cluster served HTTP on 127.0.0.1:8787
(`dashboard_address=None` does not stop the server); `--scheduler tcp://` was the only way to
a remote cluster; two `study --resume` on one folder both appended rows; `replicates:
200000000` built 3.7 GB of tasks before the first row. The TLS test makes its own certificate
authority and certificates with the `openssl` command, and runs a real `dask scheduler` and
`dask worker` on 127.0.0.1.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import signal
import socket
import subprocess
import sys
import time

from hidden_effects import FEW_SIMULATED_RUNS
import psutil
import pytest
import yaml

from octoroach_model.errors import OutputError, ParameterError
from octoroach_model.fileio import appended_lines, folder_lock
from octoroach_model.studies import run_study
from octoroach_model.workers import dask_client

REPO = Path(__file__).resolve().parents[1]
DASK = Path(sys.executable).with_name('dask')
ONE_NULL = {'name': 'one', 'seed': 1, 'runs': [40], 'robot': {'cycles': 4},
            'diagnosis': {**FEW_SIMULATED_RUNS, 'detection_limits': False}}


def listening_ports(process: psutil.Process) -> list[int]:
    ports = []
    for proc in [process, *process.children(recursive=True)]:
        try:
            ports += [c.laddr.port for c in proc.net_connections(kind='inet')
                      if c.status == psutil.CONN_LISTEN]
        except psutil.NoSuchProcess:
            pass
    return ports


def http_answer(port: int) -> bytes:
    """Return what a plain HTTP request to 127.0.0.1:`port` gets back (b'' when nothing)."""
    try:
        with socket.create_connection(('127.0.0.1', port), timeout=2) as connection:
            connection.sendall(b'GET /health HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n')
            return connection.recv(64)
    except OSError:
        return b''


def test_the_local_cluster_serves_no_http_and_speaks_only_tls():
    with dask_client(workers=1) as client:
        address = client.scheduler.address
        ports = listening_ports(psutil.Process())
        answers = {port: http_answer(port) for port in ports}
        assert client.run(os.getpid)           # the cluster works
    assert address.startswith('tls://127.0.0.1:'), address
    assert ports and not [p for p, a in answers.items() if a.startswith(b'HTTP/')], answers


def openssl(*args: str, cwd: Path) -> None:
    subprocess.run(['openssl', *args], cwd=cwd, check=True, capture_output=True, timeout=60)


def certificates(directory: Path) -> dict[str, Path]:
    """Make a certificate authority, a certificate for the cluster and one for the client."""
    openssl('req', '-x509', '-newkey', 'rsa:2048', '-nodes', '-days', '2', '-subj',
            '/CN=octoroach test CA', '-keyout', 'ca.key', '-out', 'ca.pem', cwd=directory)
    (directory / 'san.cnf').write_text('subjectAltName=IP:127.0.0.1,DNS:localhost\n')
    for name in ('cluster', 'client'):
        openssl('req', '-newkey', 'rsa:2048', '-nodes', '-subj', f'/CN={name}', '-keyout',
                f'{name}.key', '-out', f'{name}.csr', cwd=directory)
        openssl('x509', '-req', '-in', f'{name}.csr', '-CA', 'ca.pem', '-CAkey', 'ca.key',
                '-CAcreateserial', '-days', '2', '-extfile', 'san.cnf', '-out', f'{name}.pem',
                cwd=directory)
    return {name: directory / name for name in ('ca.pem', 'cluster.pem', 'cluster.key',
                                                'client.pem', 'client.key')}


def start(args: list[str], log: Path) -> subprocess.Popen:
    return subprocess.Popen(args, cwd=log.parent, stdout=log.open('wb'),
                            stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)


@pytest.mark.long
def test_a_tls_scheduler_is_reached_with_the_certificates_given_and_refused_without(tmp_path):
    files = certificates(tmp_path)
    tls = ['--tls-ca-file', str(files['ca.pem']), '--tls-cert', str(files['cluster.pem']),
           '--tls-key', str(files['cluster.key'])]
    scheduler_log, worker_log = tmp_path / 'scheduler.log', tmp_path / 'worker.log'
    scheduler = start([str(DASK), 'scheduler', '--host', '127.0.0.1', '--port', '0',
                       '--protocol', 'tls', '--no-dashboard', *tls], scheduler_log)
    processes = [scheduler]
    try:
        deadline = time.monotonic() + 60
        while not (found := re.search(r'Scheduler at:\s+(tls://\S+)', scheduler_log.read_text())):
            assert time.monotonic() < deadline and scheduler.poll() is None, \
                scheduler_log.read_text()
            time.sleep(0.2)
        address = found.group(1)
        processes.append(start([str(DASK), 'worker', address, '--nthreads', '1',
                                '--no-dashboard', *tls], worker_log))
        spec = tmp_path / 'one.yaml'
        spec.write_text(yaml.safe_dump(ONE_NULL))
        study = [sys.executable, '-m', 'octoroach_model', 'study', str(spec), '--no-plots',
                 '--scheduler', address, '--connect-timeout-s', '30']
        client_tls = ['--tls-ca-file', str(files['ca.pem']), '--tls-cert',
                      str(files['client.pem']), '--tls-key', str(files['client.key'])]

        refused = subprocess.run([*study, '--out', str(tmp_path / 'no')], cwd=REPO,
                                 capture_output=True, text=True, timeout=120)
        assert refused.returncode == 1 and 'speaks TLS: give --tls-ca-file' in refused.stderr
        done = subprocess.run([*study, '--out', str(tmp_path / 'done'), *client_tls], cwd=REPO,
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, f'{done.stderr}\n{worker_log.read_text()}'
        assert 'table: ' in done.stdout and (tmp_path / 'done' / 'summary.json').is_file()
    finally:
        for process in reversed(processes):
            process.send_signal(signal.SIGINT)
        for process in reversed(processes):
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()


HOLD = ('import sys, time; from octoroach_model.fileio import folder_lock\n'
        'with folder_lock(sys.argv[1]):\n'
        '    print("held", flush=True); time.sleep(600)\n')


def test_one_study_folder_has_one_writer_and_a_killed_one_leaves_no_stale_lock(tmp_path):
    out = tmp_path / 'study'
    run_study(ONE_NULL, out, workers=0, plots=False)
    holder = subprocess.Popen([sys.executable, '-c', HOLD, str(out)], stdout=subprocess.PIPE,
                              text=True, cwd=REPO)
    try:
        assert holder.stdout.readline().strip() == 'held'
        with pytest.raises(OutputError, match=f'another run \\(process {holder.pid}\\)'):
            run_study(ONE_NULL, out, workers=0, resume=True, plots=False)
        spec = tmp_path / 'one.yaml'
        spec.write_text(yaml.safe_dump(ONE_NULL))
        result = subprocess.run([sys.executable, '-m', 'octoroach_model', 'study', str(spec),
                                 '--out', str(out), '--resume', '--workers', '0'], cwd=REPO,
                                capture_output=True, text=True, timeout=120)
        assert result.returncode == 3 and 'being written by another run' in result.stderr, \
            result.stderr
    finally:
        holder.send_signal(signal.SIGKILL)       # a crash: the OS releases the lock
        holder.wait(timeout=10)
    resumed = run_study(ONE_NULL, out, workers=0, resume=True, plots=False)
    assert resumed.rows == 1 and resumed.computed == 0
    with folder_lock(out):
        pass


def test_a_results_log_appends_whole_lines_and_never_writes_through_a_link(tmp_path):
    """A resumable benchmark's log: a line cut by a kill stays apart from the next one."""
    log = tmp_path / 'new' / 'rows.jsonl'
    with appended_lines(log) as stream:
        stream.write('{"a": 1}\n{"b": ')             # the second line cut by an interruption
    with appended_lines(log) as stream:
        stream.write('{"c": 3}\n')
    assert log.read_text().splitlines() == ['{"a": 1}', '{"b": ', '{"c": 3}']
    target = tmp_path / 'elsewhere.txt'
    target.write_text('kept\n')
    link = tmp_path / 'link.jsonl'
    link.symlink_to(target)
    with pytest.raises(OutputError, match='symbolic link'):
        with appended_lines(link) as stream:
            stream.write('lost\n')
    assert target.read_text() == 'kept\n'
    pipe = tmp_path / 'pipe.jsonl'
    os.mkfifo(pipe)
    with pytest.raises(OutputError, match='not a regular file'):
        with appended_lines(pipe) as stream:
            stream.write('lost\n')


def test_a_study_of_absurd_size_is_refused_before_its_tasks_are_built(tmp_path):
    spec = tmp_path / 'huge.yaml'
    spec.write_text(yaml.safe_dump({**ONE_NULL, 'replicates': 200_000_000}))
    started = time.monotonic()
    result = subprocess.run([sys.executable, '-m', 'octoroach_model', 'study', str(spec),
                             '--out', str(tmp_path / 'huge'), '--workers', '0'], cwd=REPO,
                            capture_output=True, text=True, timeout=60)
    assert time.monotonic() - started < 20
    assert result.returncode == 1 and 'more than the 1000000 one study may hold' in \
        result.stderr and result.stderr.count('\n') == 1, result.stderr
    assert not (tmp_path / 'huge').exists()
    with pytest.raises(ParameterError, match='200000000 replicates'):
        run_study({**ONE_NULL, 'replicates': 200_000_000}, tmp_path / 'huge', workers=0)

"""
The local Dask cluster of a study: TLS only among its own processes, and no HTTP server.

Why: Dask runs whatever a client submits, as the workers' user, and its scheduler and workers
each serve HTTP (the dashboard, /health, /metrics, /json) on a port any local user can reach;
`dashboard_address=None` turns the dashboard off but not the server. This cluster's scheduler
and workers (`PrivateScheduler`, `PrivateWorker`) keep their HTTP routes but never open the
socket, and every connection among them is TLS under a throw-away certificate authority
(`Security.temporary()`) whose keys only this process and its workers hold.
"""
from __future__ import annotations

import logging
from typing import Any

from distributed import Nanny, Scheduler, Security, SpecCluster, Worker
from distributed.http.routing import RoutingApplication
from tornado.httpserver import HTTPServer

__all__ = ['PrivateScheduler', 'PrivateWorker', 'private_local_cluster']


def _no_http_server(node: Any, routes: Any) -> None:
    """Do what a node's `start_http_server` does, but open no socket (the routes are kept)."""
    node.http_application = RoutingApplication(routes)
    node.http_server = HTTPServer(node.http_application)


class PrivateScheduler(Scheduler):
    """A scheduler without an HTTP server."""

    def start_http_server(self, routes: Any, dashboard_address: Any, default_port: int = 0,
                          ssl_options: Any = None) -> None:
        _no_http_server(self, routes)


class PrivateWorker(Worker):
    """A worker without an HTTP server."""

    def start_http_server(self, routes: Any, dashboard_address: Any, default_port: int = 0,
                          ssl_options: Any = None) -> None:
        _no_http_server(self, routes)


def private_local_cluster(workers: int) -> SpecCluster:
    """Start `workers` single-threaded worker processes and their scheduler on 127.0.0.1."""
    security = Security.temporary()
    worker = {'cls': Nanny, 'options': {
        'nthreads': 1, 'host': '127.0.0.1', 'worker_class': PrivateWorker,
        'security': security, 'silence_logs': logging.ERROR}}
    scheduler = {'cls': PrivateScheduler, 'options': {
        'host': '127.0.0.1', 'protocol': 'tls://', 'dashboard': False,
        'dashboard_address': None, 'security': security}}
    return SpecCluster(scheduler=scheduler, workers={i: worker for i in range(workers)},
                       security=security, silence_logs=logging.ERROR, name='octoroach-study')

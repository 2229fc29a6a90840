"""Studies on a Dask cluster (a LocalCluster of two worker processes): the same seed gives results
identical bit for bit to the local run, a scheduler address works as well as a client, and an
unreachable or malformed scheduler is a clear error within seconds, never a hang."""

import time

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError
from rotorid.studies import ImpactErrors, SyncErrors, impact_study, synchronous_study
from rotorid.studies import monte_carlo as mc

distributed = pytest.importorskip("dask.distributed")

RIG = rotorid.nsf_rig()
RUNS = [RIG.imbalances[s] for s in "ABCD"]
RPM = np.linspace(2000.0, 8000.0, 23)


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as c, distributed.Client(c) as client:
        yield c, client


@pytest.fixture
def small_tasks(monkeypatch):
    """Several trial blocks and point ranges, so that the merge order matters."""
    monkeypatch.setattr(mc, "TRIAL_BLOCK", 64)
    monkeypatch.setattr(mc, "POINT_BLOCK", 8)


def _same(a, b):
    for name in ("pct", "mean", "rms", "singular", "counts"):
        if getattr(a, name) is None and getattr(b, name) is None:
            continue
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name


def test_cluster_and_local_runs_are_identical(cluster, small_tasks):
    _, client = cluster
    kw = dict(trials=300, seed=21, keep_histograms=True)
    errors = SyncErrors(amplitude_rel=0.005, phase_deg=0.2, keyphasor_deg=0.05)
    local = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, errors, **kw)
    remote = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, errors, client=client, **kw)
    _same(local, remote)
    f = np.linspace(20, 150, 17)
    ie = ImpactErrors(coherence=0.95, impacts=5, force_calibration_rel=0.01)
    tests = [(0.0, "x"), (0.0, "y")]
    li = impact_study(RIG.rotor, RIG.bearings, tests, f, ie, speed_rpm=1000, **kw)
    ri = impact_study(RIG.rotor, RIG.bearings, tests, f, ie, speed_rpm=1000, client=client, **kw)
    _same(li, ri)
    other = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, errors, client=client, trials=300, seed=22)
    assert not np.array_equal(other.pct, local.pct)
    assert not np.array_equal(other.mean, local.mean)
    # the user's client stays open and stays the default; the scattered spec is released
    assert client.status == "running"
    assert distributed.default_client() is client
    deadline = time.monotonic() + 10
    while client.who_has() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not client.who_has()


def test_a_scheduler_address_works_and_its_client_is_closed(cluster, small_tasks):
    c, _ = cluster
    errors = SyncErrors(phase_deg=0.1)
    local = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, errors, trials=100, seed=2)
    before = len(c.scheduler.clients) if hasattr(c.scheduler, "clients") else None
    remote = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, errors, trials=100, seed=2,
                               client=c.scheduler_address)
    _same(local, remote)
    f = np.linspace(20, 150, 17)
    tests = [(0.0, "x"), (0.1, "x")]
    li = impact_study(RIG.rotor, RIG.bearings, tests, f, ImpactErrors(coherence=0.97), speed_rpm=500, trials=100,
                      seed=3)
    ri = impact_study(RIG.rotor, RIG.bearings, tests, f, ImpactErrors(coherence=0.97), speed_rpm=500, trials=100,
                      seed=3, client=c.scheduler_address)
    _same(li, ri)
    assert distributed.default_client() is cluster[1]  # the address's client no longer the default
    if before is not None:
        deadline = time.monotonic() + 10
        while len(c.scheduler.clients) > before and time.monotonic() < deadline:
            time.sleep(0.1)
        assert len(c.scheduler.clients) <= before


@pytest.mark.parametrize("workers", [2, 3])
def test_local_threads_change_nothing(monkeypatch, workers):
    errors = SyncErrors(amplitude_rel=0.005, phase_deg=0.2)
    monkeypatch.setattr(mc, "TRIAL_BLOCK", 32)
    monkeypatch.setattr(mc, "POINT_BLOCK", 8)
    monkeypatch.setattr(mc, "LOCAL_WORKERS", 1)
    one = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, errors, trials=200, seed=5, keep_histograms=True)
    f = np.linspace(20, 150, 17)
    ie = ImpactErrors(coherence=0.95, impacts=5)
    one_i = impact_study(RIG.rotor, RIG.bearings, [(0.0, "x"), (0.0, "y")], f, ie, speed_rpm=1000, trials=200, seed=5,
                         keep_histograms=True)
    monkeypatch.setattr(mc, "LOCAL_WORKERS", workers)
    many = synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, errors, trials=200, seed=5, keep_histograms=True)
    many_i = impact_study(RIG.rotor, RIG.bearings, [(0.0, "x"), (0.0, "y")], f, ie, speed_rpm=1000, trials=200,
                          seed=5, keep_histograms=True)
    _same(one, many)
    _same(one_i, many_i)


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:1", "not-an-address"])
def test_unreachable_scheduler_is_a_clear_error_within_seconds(address):
    t = time.monotonic()
    with pytest.raises(RotoridError, match="scheduler"):
        synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, trials=10, client=address)
    assert time.monotonic() - t < 30


@pytest.mark.parametrize("client", [42, "", object()])
def test_not_a_client(client):
    with pytest.raises(RotoridError, match="client|scheduler"):
        synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, trials=10, client=client)


def test_a_closed_client_is_an_error(cluster):
    c, _ = cluster
    closed = distributed.Client(c.scheduler_address, set_as_default=False)
    closed.close()
    with pytest.raises(RotoridError, match="closed"):
        synchronous_study(RIG.rotor, RIG.bearings, RUNS, RPM, trials=10, client=closed)

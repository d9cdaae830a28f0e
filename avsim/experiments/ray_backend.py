"""The `ray` backend of `run_batch`: a batch's runs as Ray tasks, on a cluster or on this machine.

    records = run_batch(specs, workers=2, backend="ray")                  # a local 2-CPU Ray cluster
    records = run_batch(specs, backend="ray", address="auto")             # the cluster this node is part of
    avsim sweep FILE --out DIR --backend ray --address 10.0.0.5:6379

Why: the local pool stops at one machine's cores; a Ray cluster spreads the same runs over many.

Each task is `avsim.experiments.run_task.execute_group(specs, root)` on one lock-step group (see
`avsim.experiments.plan.lockstep_groups`), the function a local pool worker runs, in a Ray worker process: a fresh Python process, so it builds its own MuJoCo model and
EGL context as a spawned pool worker does. A task asks for one CPU (a run is single-threaded,
see `PerceptionConfig.threads`; a lock-step group shares that thread), so a node runs as many at
once as it has CPUs. The specs (`RunSpec`, its `SimConfig` a frozen dataclass) are pickled to
the worker; the records come back.

What it guarantees, as the local pool does: one record per spec, handed over in finishing
order; the same record for the same spec on either backend (a run is seeded by its config;
`wall_s` aside); a run that raises is a `failed` record. Beyond the pool: a worker process
that dies (a crash, out of memory, a lost node) is run again by Ray up to `MAX_RETRIES`
times, then each run of its group is a `failed` record, and the batch goes on.

What it needs from a cluster: on every node, avsim at the same version with the same Python
and Ray, and the files the configs name (sign textures, detector weights) at the same paths.
A run's `.rrd` (`RunSpec.rrd_path`) is written on the node that ran it. `ray://` client
addresses need `pip install 'ray[client]'` as well. A cluster with token authentication (on by
default for clusters Ray 2.60 starts) is joined with `RAY_AUTH_MODE=token` and the cluster's
token in `~/.ray/auth_token` (or `RAY_AUTH_TOKEN`). Ray keeps retrying an address where no
cluster answers; stop it with Ctrl-C.

What a cluster's runs ran on: a batch's manifest describes this machine (`avsim.software.software_versions`),
and a cluster's nodes render and infer with their own GL, CPU and libraries. So before a batch at an address,
`cluster_nodes` asks every node that can take a run what it runs; the manifest keeps the answers
(`cluster_nodes`), and a node whose GL, instruction set, arithmetic or library versions differ from this
machine's is a warning: a run's numbers may then depend on the node that ran it.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import warnings
from collections.abc import Iterator
from typing import Any

from avsim.errors import ConfigError
from avsim.experiments.plan import Group, in_flight, specs_of
from avsim.experiments.run_task import execute_group, failed_record, worker_env
from avsim.software import differences, software_versions

INSTALL_HINT = "pip install 'avsim[ray]'"
# Times Ray reruns a task whose worker process died before the run is recorded as failed.
MAX_RETRIES = 2


def require_ray() -> Any:
    """The `ray` module, or a one-line ConfigError naming the install command."""
    try:
        import ray
    except ImportError:
        raise ConfigError(f"the ray backend needs Ray, which is not installed: {INSTALL_HINT}") from None
    return ray


def check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """A one-line ConfigError unless a Ray cluster's port answers at `address` within `timeout_s`.

    Checked before a batch writes anything: `ray.init` itself keeps retrying a dead address for
    minutes. "auto" (the cluster this machine belongs to) is left to Ray, which fails fast.
    """
    if address == "auto":
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise ConfigError(f"Ray address '{address}' must be auto, HOST:PORT or ray://HOST:PORT")
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as exc:
        raise ConfigError(f"no Ray cluster answers at '{address}' ({exc.strerror or exc}); start one with "
                          "'ray start --head' or fix --address") from None
    _check_ray_answers(address, RAY_CONNECT_TIMEOUT_S)


# A port that accepts connections may still be no Ray cluster (another service, a cluster
# that is starting or broken), and then `ray.init` retries for a minute, logging as it goes,
# with no timeout of its own (ray-project/ray#46863). So a child process connects first, its
# output captured, and is given this long [s]; a live cluster answers in a few seconds.
RAY_CONNECT_TIMEOUT_S = 10.0
_PROBE = ("import logging, sys, ray; ray.init(address=sys.argv[1], logging_level=logging.ERROR, log_to_driver=False, "
          "include_dashboard=False); ray.shutdown()")


def _check_ray_answers(address: str, timeout_s: float) -> None:
    """A one-line ConfigError unless `ray.init(address)` succeeds in a child process within `timeout_s`."""
    try:
        probe = subprocess.run([sys.executable, "-c", _PROBE, address], capture_output=True, text=True,
                               timeout=timeout_s, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise ConfigError(f"no Ray cluster answers at '{address}' within {timeout_s:g} s (something listens on "
                          "the port, but Ray does not connect); check the address and that the cluster is up "
                          "(`ray status`)") from None
    if probe.returncode != 0:
        lines = [line.strip() for line in probe.stderr.splitlines() if line.strip()]
        raise ConfigError(f"no Ray cluster answers at '{address}' ({lines[-1] if lines else 'ray.init failed'}); "
                          "check the address and that the cluster is up (`ray status`)")


@contextlib.contextmanager
def session(address: str | None, workers: int | None) -> Iterator[Any]:
    """A Ray session for one batch; yields the `ray` module.

    address None: start a local cluster of `workers` CPUs, stopped on exit. address given:
    connect to that cluster ("auto", "HOST:6379", "ray://HOST:10001"), disconnect on exit.
    A session the caller already started (`ray.init` before) is used as it is, and left open.
    """
    ray = require_ray()
    if ray.is_initialized():
        yield ray
        return
    if address is None:
        if workers is None or workers < 1:
            raise ConfigError(f"a local Ray cluster needs workers >= 1, got {workers}")
        # Its workers inherit this process's environment, MUJOCO_GL included, plus their
        # share of the cores for the rasteriser (`run_task.worker_env`).
        ray.init(num_cpus=workers, include_dashboard=False, runtime_env={"env_vars": worker_env(workers)})
    else:
        # A remote node has its own environment: send the renderer this driver chose (avsim defaults to EGL).
        env = {"env_vars": {"MUJOCO_GL": os.environ["MUJOCO_GL"]}} if "MUJOCO_GL" in os.environ else None
        ray.init(address=address, runtime_env=env)
    try:
        yield ray
    finally:
        ray.shutdown()


def ray_results(groups: Iterator[Group], root: str | None, *, workers: int | None,
                address: str | None) -> Iterator[tuple[int, dict[str, Any]]]:
    """Run lock-step groups (`avsim.experiments.plan.lockstep_groups`: specs, each with its index)
    as Ray tasks, one a group; yield (index, record) for each run of a group as the group finishes.

    workers: the local cluster's CPUs when address is None; with an address, at most that many
    tasks in flight (None: twice the cluster's CPUs, so a node never waits for its next task).
    Groups are drawn from `groups` only as tasks finish, so a large plan is never submitted whole.
    """
    with session(address, workers) as ray:
        task = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(execute_group)
        limit = workers if workers is not None else 2 * max(1, int(ray.cluster_resources().get("CPU", 1)))

        def submit(group: Group) -> Any:
            return task.remote(specs_of(group), root)

        def first_done(refs: Any) -> Any:
            return ray.wait(list(refs), num_returns=1)[0][0]

        # Stopped early (an error in the caller, Ctrl-C): the cluster need not finish the batch.
        for group, ref in in_flight(groups, limit, submit, first_done, ray.cancel):
            try:
                records = ray.get(ref)
            except ray.exceptions.RayError as exc:  # worker died MAX_RETRIES + 1 times, or task lost
                error = f"{type(exc).__name__}: {_first_line(exc)}"
                records = [failed_record(spec, error) for _, spec in group]
            yield from zip((index for index, _ in group), records)


def _first_line(exc: BaseException) -> str:
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    return lines[0] if lines else "no message"


# How long the nodes may take to say what they run [s]: a node's first task starts a Python that imports
# torch and MuJoCo and opens a GL context, a few seconds on a warm node.
NODE_PROBE_TIMEOUT_S = 120.0


def _this_node() -> dict[str, str]:
    """Run on a node: its IP address and what it runs (`avsim.software.software_versions`)."""
    import ray

    return {"node": ray.util.get_node_ip_address(), **software_versions()}


def node_versions(address: str | None, timeout_s: float = NODE_PROBE_TIMEOUT_S) -> list[dict[str, str]]:
    """What each live node of the Ray cluster at `address` that has CPUs for a run runs, sorted by node.

    One entry a node: {"node": its IP, then `software_versions()`'s keys, as read on that node}, or
    {"node": ..., "error": why it did not answer} for a node whose probe failed or took over `timeout_s`.
    address None: the session already started in this process (a local cluster: this machine).
    """
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    with session(address, None) as ray:
        nodes = [n for n in ray.nodes() if n.get("Alive") and n.get("Resources", {}).get("CPU", 0) > 0]
        # No CPU asked, so a node whose CPUs are all taken still answers.
        probe = ray.remote(num_cpus=0, max_retries=0)(_this_node)
        refs = [probe.options(scheduling_strategy=NodeAffinitySchedulingStrategy(n["NodeID"], soft=False)).remote()
                for n in nodes]
        ready, _ = ray.wait(refs, num_returns=len(refs), timeout=timeout_s)
        answers = []
        for node, ref in zip(nodes, refs):
            name = node.get("NodeManagerAddress", node["NodeID"])
            if ref not in ready:
                ray.cancel(ref, force=True)
                answers.append({"node": name, "error": f"no answer within {timeout_s:g} s"})
                continue
            try:
                answers.append(ray.get(ref))
            except ray.exceptions.RayError as exc:
                answers.append({"node": name, "error": f"{type(exc).__name__}: {_first_line(exc)}"})
    return sorted(answers, key=lambda answer: answer["node"])


def cluster_nodes(backend: str, address: str | None) -> list[dict[str, str]] | None:
    """For a batch about to run on the Ray cluster at `address`: what each node runs (`node_versions`), for
    the manifest; a warning where a node differs from this machine (`differences`). None where the runs
    run on this machine (the local backend, or a local Ray cluster), whose manifest `versions` describes them."""
    if backend != "ray" or address is None:
        return None
    nodes = node_versions(address)
    if not nodes:
        warnings.warn(f"the Ray cluster at {address} had no node with CPUs when asked what its nodes run (one may "
                      "join later, as an autoscaler adds it), so the manifest cannot say what the runs ran on",
                      stacklevel=2)
    phrases = differences(software_versions(), nodes)
    if phrases:
        warnings.warn(f"the Ray cluster at {address} is not this machine's twin: {'; '.join(phrases)}; a run's numbers "
                      "may then depend on the node that ran it (the manifest's cluster_nodes lists every node)",
                      stacklevel=2)
    return nodes

"""How much memory a new allocation of this process can get, from every limit that applies: the
machine's free memory, this process's own limits (`ulimit -v` / `ulimit -d`: RLIMIT_AS and RLIMIT_DATA)
and its cgroup's (v2 `memory.max`, v1 `memory.limit_in_bytes`, at every level of its cgroup path).

Why all of them: a container or a `ulimit` makes an allocation fail long before the machine's memory
runs out; a check that read only /proc/meminfo let 60,000 envs past a 3 GB limit, to fail inside
MuJoCo. Training (`lasmp.cli.resources`) and the trajectory generator check against it before any
allocation. The cgroup and proc paths are arguments so that tests can give mocked files."""

from __future__ import annotations

import contextlib
import os
import resource
from pathlib import Path

from lasmp.io.inputs import size_in_words

CGROUP_ROOT = Path("/sys/fs/cgroup")
PROC_SELF = Path("/proc/self")
# (resource, the ulimit flag, the /proc/self/status line of what the process already holds against it)
RLIMITS = ((resource.RLIMIT_AS, "-v", "VmSize"), (resource.RLIMIT_DATA, "-d", "VmData"))


def available_memory(cgroup_root: Path = CGROUP_ROOT, proc_self: Path = PROC_SELF) -> tuple[int, str] | None:
    """The memory a new allocation can get, in bytes, and where the figure comes from: the tightest of
    the machine's MemAvailable, this process's address-space and data limits less what it already holds,
    and each cgroup limit along its path less that cgroup's usage; None where none can be read."""
    found = [*_machine(), *_rlimits(proc_self), *_cgroups(cgroup_root, proc_self)]
    return min(found, key=lambda f: f[0]) if found else None


def _machine() -> list[tuple[int, str]]:
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return [(int(line.split()[1]) * 1024, "MemAvailable in /proc/meminfo")]
    with contextlib.suppress(ValueError, OSError, AttributeError):
        return [(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"), "free physical pages")]
    return []


def _status_kib(proc_self: Path) -> dict[str, int]:
    sizes = {}
    with contextlib.suppress(OSError, ValueError):
        for line in (proc_self / "status").read_text().splitlines():
            key, _, rest = line.partition(":")
            if rest.strip().endswith("kB"):
                sizes[key] = int(rest.split()[0]) * 1024
    return sizes


def _rlimits(proc_self: Path) -> list[tuple[int, str]]:
    held = _status_kib(proc_self)
    found = []
    for which, flag, line in RLIMITS:
        soft, _ = resource.getrlimit(which)
        if soft == resource.RLIM_INFINITY:
            continue
        used = held.get(line, 0)
        name = "RLIMIT_AS" if which == resource.RLIMIT_AS else "RLIMIT_DATA"
        found.append(
            (
                max(soft - used, 0),
                f"this process's limit `ulimit {flag}` ({name}) of {size_in_words(soft)} less the "
                f"{size_in_words(used)} it holds ({line})",
            )
        )
    return found


def _cgroup_paths(proc_self: Path) -> dict[str, str]:
    """The process's cgroup path per hierarchy: "" for v2 (`0::/path`), "memory" for v1's memory."""
    paths = {}
    with contextlib.suppress(OSError):
        for line in (proc_self / "cgroup").read_text().splitlines():
            parts = line.split(":", 2)
            if len(parts) != 3:
                continue
            if parts[0] == "0" and parts[1] == "":
                paths[""] = parts[2]
            elif "memory" in parts[1].split(","):
                paths["memory"] = parts[2]
    return paths


def _levels(base: Path, path: str) -> list[Path]:
    """`base`/`path` and each of its parents up to `base`: a limit set higher up binds as well."""
    here = base / path.strip("/")
    return [here, *[p for p in here.parents if p.is_relative_to(base)]]


def _cgroups(root: Path, proc_self: Path) -> list[tuple[int, str]]:
    paths = _cgroup_paths(proc_self)
    found = []
    versions = (
        ("", "memory.max", "memory.current"),
        ("memory", "memory.limit_in_bytes", "memory.usage_in_bytes"),
    )
    for hierarchy, limit_file, usage_file in versions:
        base = root / hierarchy
        for level in _levels(base, paths.get(hierarchy, "/")):
            with contextlib.suppress(OSError, ValueError):
                text = (level / limit_file).read_text().strip()
                if text == "max":
                    continue
                limit = int(text)
                usage = 0
                with contextlib.suppress(OSError, ValueError):
                    usage = int((level / usage_file).read_text())
                found.append(
                    (
                        max(limit - usage, 0),
                        f"the cgroup limit {level / limit_file} of {size_in_words(limit)} less its "
                        f"{size_in_words(usage)} in use ({usage_file})",
                    )
                )
    return found

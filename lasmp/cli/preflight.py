"""What the user's machine brings, checked before the work starts: environment variables, optional
packages and credentials that a command needs. Without these checks each failed late, in a traceback
of the library that met it: MUJOCO_GL at `import mujoco`, a missing W&B login after the envs were
built, a missing MuJoCo Warp inside the env's construction. Each check gives one line naming the
cause and the fix.

`exit_unless_mujoco_imports` runs first in train.py, play.py and evaluate.py (after lasmp.io.ctrl_c,
before anything imports mujoco); `training_environment_error` in `lasmp.cli.train.train`, before any env is
built; `backend_error` also where play and evaluation rebuild a checkpoint's env (`lasmp.deploy`)."""

from __future__ import annotations

import os
import sys
import traceback
from pathlib import Path

# W&B modes in which a run writes locally and needs no login (wandb.init's own test, Settings.mode)
WANDB_LOCAL_MODES = ("offline", "dryrun", "disabled")


def mujoco_import_error() -> str | None:
    """Why `import mujoco` fails in this environment, in one line, or None. mujoco picks its OpenGL
    backend from MUJOCO_GL when it is imported: an unknown value (`bogus`) raises there, and a backend
    whose library is missing (`osmesa` without libosmesa6) can fail there too."""
    try:
        import mujoco  # noqa: F401
    except Exception as err:  # whatever the import meets: RuntimeError, ImportError, AttributeError
        why = f"{type(err).__name__}: {(str(err).strip().splitlines() or [''])[0]}"
        if isinstance(err, ModuleNotFoundError) and err.name == "mujoco":
            return f"mujoco is not installed in this Python ({sys.executable}): activate the project's environment"
        gl = os.environ.get("MUJOCO_GL")
        if gl is not None and _in_gl_code(err):
            return (
                f"mujoco cannot be imported with MUJOCO_GL={gl} ({why}): unset MUJOCO_GL, or set it to egl "
                "(a GPU driver or Mesa's EGL), osmesa (with libosmesa6 installed) or glfw (with a display)"
            )
        return f"mujoco cannot be imported ({why}): reinstall it in this environment (pip install -e .)"
    return None


def _in_gl_code(err: BaseException) -> bool:
    """Whether the failure of `import mujoco` came from its choice of OpenGL backend (MUJOCO_GL)."""
    if "MUJOCO_GL" in str(err):
        return True
    places = ("rendering", "egl", "osmesa", "glfw", "cgl", "OpenGL")
    frames = traceback.extract_tb(err.__traceback__)
    return any(part in places for f in frames for part in Path(f.filename).parts)


def exit_unless_mujoco_imports() -> None:
    """For the entry points: `error: ...` and exit 2 where mujoco cannot be imported."""
    error = mujoco_import_error()
    if error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)


def backend_error(backend: str, needs: str = "env.backend=warp needs") -> str | None:
    """Why env.backend=`backend` cannot run here, or None: `warp` needs the gpu extra (mujoco-warp and
    warp-lang), imported here as the env would import them (a broken install fails here too). `needs`
    starts the message (whose env it is)."""
    if backend != "warp":
        return None
    try:
        import mujoco_warp  # noqa: F401
        import warp  # noqa: F401
    except Exception as err:
        return (
            f"{needs} MuJoCo Warp, which cannot be imported ({type(err).__name__}: {err}); install it with "
            'pip install -e ".[gpu]" (the gpu extra: mujoco-warp and warp-lang)'
        )
    return None


def wandb_login_error() -> str | None:
    """Why runner.logger=wandb would fail at its first iteration for want of a login, or None: W&B
    asks for an API key (from WANDB_API_KEY, `wandb login`'s ~/.netrc or its settings) unless its mode
    is offline or disabled (WANDB_MODE, or `wandb offline`). Without one, wandb.init stops the run
    (no terminal) or prompts at it after the envs were built; both are refused here, up front. The
    package itself is `lasmp.config.train.validate_logger`'s to check."""
    if os.environ.get("WANDB_MODE", "").strip().lower() in WANDB_LOCAL_MODES:
        return None
    if os.environ.get("WANDB_API_KEY") or os.environ.get("WANDB_IDENTITY_TOKEN_FILE"):
        return None  # a malformed key is W&B's to report
    try:
        import wandb

        settings = wandb.setup().settings  # the mode and host wandb.init will use (env, settings files)
        if settings.mode in WANDB_LOCAL_MODES:
            return None
        from wandb.sdk.lib.wbauth import authenticate  # W&B's own lookup: env, ~/.netrc, settings

        found = authenticate.authenticate_session(
            host=settings.base_url, source="lasmp", prompt=False, update_session=False
        )
    except (ImportError, AttributeError, TypeError):  # another wandb version: wandb.init judges
        return None
    except Exception as err:  # credentials found but unusable (a malformed key, two sources)
        return f"runner.logger=wandb: W&B's credentials are unusable ({type(err).__name__}: {err})"
    if found is not None:
        return None
    return (
        "runner.logger=wandb needs a W&B login and none was found (no WANDB_API_KEY, no `wandb login`): "
        "run `wandb login`, set WANDB_API_KEY, or set WANDB_MODE=offline to log locally (`wandb sync` "
        "uploads the run later)"
    )


def training_environment_error(cfg) -> str | None:
    """The first reason a training of `cfg` (a TrainCfg) cannot run in this environment, or None."""
    if cfg.runner.logger == "wandb":
        error = wandb_login_error()
        if error:
            return error
    return backend_error(cfg.env.backend)

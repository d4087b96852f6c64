"""PlatformIO post-build hook (extra_scripts): `python -m metacell_tools.fwcheck lint --elf <firmware.elf>`."""

# Klipper-style build-time guard: the project's own checker looks for soft-float and
# division helpers in the control path of the linked image. The hook is fatal when the
# checker runs and fails, and a warning (build continues) when the checker, or its
# `lint` command, is not installed. MC_FWCHECK=skip in the environment bypasses it.
import os
import subprocess

Import("env")  # type: ignore[name-defined]  # noqa: F821  (SCons injects Import and env)

# Interrupt entry points of the cell glue (src/cell/samd21_hw.h), checked in addition
# to the library's control-path roots; roots absent from an image (primary) are skipped.
GLUE_ROOTS = ("TC3_Handler", "hw_isr_encoder_alpha", "hw_isr_encoder_beta")


def _python(project_dir):
    venv = os.path.join(project_dir, ".venv", "bin", "python")
    return venv if os.path.exists(venv) else env.subst("$PYTHONEXE")  # type: ignore[name-defined]  # noqa: F821


def _fwcheck(source, target, env):
    project = env.subst("$PROJECT_DIR")
    if os.environ.get("MC_FWCHECK", "") == "skip":
        print("fwcheck: skipped (MC_FWCHECK=skip)")
        return 0
    python = _python(project)
    probe = subprocess.run(
        [python, "-m", "metacell_tools.fwcheck", "--help"], cwd=project, capture_output=True, text=True
    )
    if probe.returncode != 0 or "lint" not in probe.stdout:
        print(
            "fwcheck: WARNING `python -m metacell_tools.fwcheck lint` is not available; "
            "soft-float/division check of the image NOT run"
        )
        return 0
    elf = str(target[0])
    # the primary image holds no control law: check its own steady path (poll scheduler, SLCAN)
    role = "primary" if env.subst("$PIOENV") == "primary" else "cell"  # noqa: F821
    roots = []
    if role == "cell":
        for r in GLUE_ROOTS:
            roots += ["--root", r]
    rc = subprocess.call(
        [python, "-m", "metacell_tools.fwcheck", "lint", "--role", role, "--elf", elf] + roots, cwd=project
    )
    if rc != 0:
        print(f"fwcheck: FAILED on {elf} (exit {rc})")
    return rc


env.AddPostAction("$BUILD_DIR/${PROGNAME}.elf", _fwcheck)  # type: ignore[name-defined]  # noqa: F821

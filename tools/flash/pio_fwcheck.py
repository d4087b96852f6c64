"""PlatformIO post-build hook (extra_scripts): run `python -m tools.fwcheck --elf <firmware.elf>`."""
# Klipper-style build-time guard: the project's own checker looks for soft-float and
# division helpers in the control path of the linked image. The hook is fatal when the
# checker runs and fails, and a warning (build continues) when the checker is not
# installed. MC_FWCHECK=skip in the environment bypasses it.
import os
import subprocess

Import("env")  # noqa: F821  (SCons injects Import)


def _python(project_dir):
    venv = os.path.join(project_dir, ".venv", "bin", "python")
    return venv if os.path.exists(venv) else env.subst("$PYTHONEXE")  # noqa: F821


def _fwcheck(source, target, env):
    project = env.subst("$PROJECT_DIR")
    if os.environ.get("MC_FWCHECK", "") == "skip":
        print("fwcheck: skipped (MC_FWCHECK=skip)")
        return 0
    python = _python(project)
    probe = subprocess.run(
        [python, "-c", "import importlib.util as u, sys; "
         "sys.exit(0 if u.find_spec('tools.fwcheck.__main__') else 1)"],
        cwd=project, capture_output=True)
    if probe.returncode != 0:
        print("fwcheck: WARNING tools.fwcheck is not available; "
              "soft-float/division check NOT run")
        return 0
    elf = str(target[0])
    rc = subprocess.call([python, "-m", "tools.fwcheck", "--elf", elf], cwd=project)
    if rc != 0:
        print("fwcheck: FAILED on %s (exit %d)" % (elf, rc))
    return rc


env.AddPostAction("$BUILD_DIR/${PROGNAME}.elf", _fwcheck)  # noqa: F821

"""PlatformIO pre-build hook of env:native: generate the bus-vector headers into the build dir for the Unity suites."""

# The vectors live in tests/firmware/vectors (pytest reads the same modules); the headers are build output, written
# to $BUILD_DIR/vectors by `python -m tests.firmware.vectors` and put on the include path. A failure stops the build.
import os
import subprocess

Import("env")  # noqa: F821  (SCons injects Import)

project = env.subst("$PROJECT_DIR")  # noqa: F821
out = os.path.join(env.subst("$BUILD_DIR"), "vectors")  # noqa: F821
venv = os.path.join(project, ".venv", "bin", "python")
python = venv if os.path.exists(venv) else env.subst("$PYTHONEXE")  # noqa: F821
r = subprocess.run(
    [python, "-m", "tests.firmware.vectors", out],
    cwd=project,
    capture_output=True,
    text=True,
    env=dict(os.environ, PYTHONDONTWRITEBYTECODE="1"),
)
if r.returncode != 0:
    print(r.stdout + r.stderr)
    print("vectors: FAILED to generate the bus-vector headers (python -m tests.firmware.vectors)")
    env.Exit(1)  # noqa: F821
env.Append(CPPPATH=[out])  # noqa: F821

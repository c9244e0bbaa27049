"""``python -m heatparam`` and the ``heatparam`` console script.

The SIGINT handler goes in before the CLI's imports (numpy, scipy, libigl: about a second), so Ctrl-C at any moment
after the interpreter has started ends with one line, exit code 130 and nothing written, never a traceback.
"""

from __future__ import annotations

import os
import sys


def main(argv: list[str] | None = None) -> int:
    """The process entry point (it may end the process: use ``heatparam.cli.main`` in-process)."""
    try:
        from heatparam import interrupt  # its `import signal` builds enums: a Ctrl-C can land in there

        interrupt.install()
    except KeyboardInterrupt:  # before the handler is in, Python's own raises KeyboardInterrupt (CI, loaded machine)
        print("heatparam: interrupted (no output written)", file=sys.stderr)
        sys.stderr.flush()
        os._exit(130)
    try:
        cli = interrupt.guarded_import("heatparam.cli")
        code = cli.main(argv)
    except KeyboardInterrupt:
        print("heatparam: interrupted (no output written)", file=sys.stderr)
        code = 130
    except SystemExit as exc:  # argparse: --help, --version, a malformed command line
        if exc.code is None or isinstance(exc.code, int):
            code = exc.code or 0
        else:
            print(exc.code, file=sys.stderr)
            code = 1
    interrupt.finish()  # nothing is left to stop: a later interrupt is only noted
    # Leave directly: (1) CPython remembers a KeyboardInterrupt raised inside a native extension's embedded Python
    # code (pybind11's exec during libigl's import) even after it was caught, and would end the process by SIGINT
    # (status -2) instead of 130; (2) the interpreter's finalization (a second or so with numpy, scipy, MKL) restores
    # the default SIGINT action, so a late Ctrl-C would kill a finished run with -2. Every output is already
    # complete and closed (atomic renames), and there is nothing else to clean up.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    sys.exit(main())

"""A script's ``main(argv)`` run in the test's own process, read as ``python -m`` would leave it (test
helper). A usage error is checked before the script does any work, so a subprocess per bad argument
spent nearly all its time importing numpy, numba, torch, SB3 and Ray again; the tests that check one
error each run it here, and keep one case per script in a subprocess (its real entry point, exit
status and a standard error free of import-time noise).

What a subprocess would show and this keeps: the exit status (SystemExit's code; 0 when ``main``
returns, 1 for a message), standard output and error at file-descriptor level (``capfd``: a logger
that holds the interpreter's own stream writes there too), and the warnings ``main`` raises, written
to standard error under the interpreter's default filters (as a fresh process prints them, each
location once). An exception other than SystemExit propagates (a subprocess would print its
traceback and exit 1). The environment variables and torch's thread count that a script sets for
itself are given back afterwards, and ``main`` runs from the repository root, as the subprocesses did.
"""
import os
import subprocess
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: The interpreter's warning filters when started without -W or -X dev (but the one that shows
#: DeprecationWarning in __main__, which a script's main called here is not); any other warning
#: is printed, once per location.
DEFAULT_FILTERS = [("ignore", DeprecationWarning), ("ignore", PendingDeprecationWarning), ("ignore", ImportWarning),
                   ("ignore", ResourceWarning)]


def call_main(main, args, capfd) -> subprocess.CompletedProcess:
    """``main(list(map(str, args)))`` here: ``CompletedProcess(args, returncode, stdout, stderr)``."""
    import torch  # the agents' scripts set its threads; imported here, its default is known

    argv = [str(a) for a in args]
    environ = dict(os.environ)
    threads = torch.get_num_threads()
    cwd = os.getcwd()
    capfd.readouterr()  # what the test printed before is not the script's
    code = 0
    try:
        os.chdir(ROOT)
        with warnings.catch_warnings(record=True) as caught:
            warnings.resetwarnings()
            for action, category in DEFAULT_FILTERS:
                warnings.filterwarnings(action, category=category)
            try:
                main(argv)
            except SystemExit as done:
                if isinstance(done.code, str):
                    print(done.code, file=sys.stderr)
                code = 1 if isinstance(done.code, str) else done.code or 0
        for w in caught:
            sys.stderr.write(warnings.formatwarning(w.message, w.category, w.filename, w.lineno, w.line))
    finally:
        os.chdir(cwd)
        os.environ.clear()
        os.environ.update(environ)
        torch.set_num_threads(threads)
    out = capfd.readouterr()
    return subprocess.CompletedProcess(argv, code, out.out, out.err)

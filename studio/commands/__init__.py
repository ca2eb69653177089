"""One module per ``studio`` command: ``run(args: argparse.Namespace) -> int``.

These are the only glue between the command line and the library; the parser is in :mod:`studio.cli`.
"""

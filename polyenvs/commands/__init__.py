"""The ``polyenvs`` subcommands, one module each with ``add_parser(subparsers)`` and ``run(args) -> int``.

:mod:`polyenvs.cli` assembles them; :mod:`polyenvs.commands.flags` holds what they share
(flag parsers, one-line errors, the progress bar). A command module imports only light modules at its top and
the heavy ones (torch, the environments) inside ``run``, so ``polyenvs --help`` stays fast.
"""

"""One module per ``teleprog`` subcommand.

Each module defines ``register(sub)``, which adds its subparser(s) to the top-level subparsers
and sets ``handler`` to a function ``(args) -> exit code``. ``server.cli`` discovers the modules
here by name, so adding a subcommand never edits a shared file. Modules import heavy packages
inside their handlers, so ``teleprog --help`` stays fast.
"""

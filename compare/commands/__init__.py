"""The ``tippetop`` commands: one module each, with the same two entry points.

``add_parser(sub)`` declares the subcommand and its options on the subparsers of
``tippetop``'s parser and sets ``func=run``; ``run(args)`` does the command and returns its
exit status. :mod:`.options` declares once what several commands share (the parser class,
exit statuses, ``--set``, ``--json`` ...). A command may import every other room of
:mod:`tippetop.compare`; none of them imports a command. :mod:`tippetop.compare.cli` lists
the commands.
"""

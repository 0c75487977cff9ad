"""One module per ``percept`` subcommand, in one subpackage per kind of work (a robot at work, its
bring-up, recorded frames, the simulated world); see :mod:`percept.runtime.cli` for the
contract. Modules whose names start with ``_`` hold what several commands share: here what
commands of several subpackages read (``_sequence``: recorded frames), in a subpackage what its
own commands do."""

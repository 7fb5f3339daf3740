"""Subcommands of `lander`: one module per subcommand, each with add_arguments(parser) and
run(args) -> int (see lander_tools.cli)."""

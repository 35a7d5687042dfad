"""The command line's commands, one module each (``scenarios.cli`` builds the parser and
dispatches): ``add_parser(sub)`` declares a command's options and ``run(args)`` does its
work and returns the exit status; ``options`` holds what they share. Module level stays
light (argparse and the scenario registry): the work's imports are inside ``run``."""

"""`lander scenes`: list the scenarios `lander fly` accepts (from lander_sim.scenes.list_scenes)."""

import argparse
import json
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print a JSON list of {name, aliases, description}")


def run(args: argparse.Namespace) -> int:
    try:
        from lander_sim.scenes import list_scenes
    except ImportError as exc:
        print(f"lander scenes: scene catalogue not available ({exc})", file=sys.stderr)
        return 2
    scenes = list_scenes()
    if args.json:
        print(json.dumps([{"name": s.name, "aliases": list(s.aliases), "description": s.description}
                          for s in scenes], indent=2))
        return 0
    if not scenes:
        print("no scenes found", file=sys.stderr)
        return 1
    width = max(len(s.name) for s in scenes)
    for s in scenes:
        aliases = f" (also: {', '.join(s.aliases)})" if s.aliases else ""
        print(f"{s.name:<{width}}  {s.description}{aliases}")
    return 0

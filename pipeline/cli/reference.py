"""The command reference (docs/reference.md): every command's ``--help``, in the order
``ftsweep --help`` lists them, rendered by click itself at a fixed width so that the page is
the same on every machine. ``python -m ftsweep.cli.reference > docs/reference.md`` writes
it; a test keeps the page equal to what this renders, so a changed option shows as a diff.
"""

from __future__ import annotations

import click

WIDTH = 100


def _helps(command: click.Command, path: list[str], parent: click.Context | None) -> list[tuple[str, str]]:
    """(full command name, help text) of ``command`` and, for a group, of each of its
    commands in the order the group lists them."""
    ctx = click.Context(
        command, info_name=path[-1], parent=parent, terminal_width=WIDTH, max_content_width=WIDTH
    )
    found = [(" ".join(path), command.get_help(ctx))]
    if isinstance(command, click.Group):
        for name in command.list_commands(ctx):
            sub = command.get_command(ctx, name)
            if sub is not None and not sub.hidden:
                found += _helps(sub, [*path, name], ctx)
    return found


def render() -> str:
    """The reference page as Markdown."""
    from ftsweep.cli.main import main

    helps = _helps(main, ["ftsweep"], None)
    lines = [
        "# ftsweep command reference",
        "",
        "Every command's `--help`, in the order `ftsweep --help` lists them: the workflow (sweep,",
        "status, select, export, verify) first. Generated from the commands themselves",
        "(`python -m ftsweep.cli.reference > docs/reference.md`; tests/house/test_citations.py keeps",
        "this page equal to their help). The user guide is docs/guide.md.",
        "",
        *(f"- [{name}](#{name.replace(' ', '-')})" for name, _ in helps),
        "",
    ]
    for name, text in helps:
        lines += [f"## {name}", "", "```text", text.rstrip(), "```", ""]
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover - a writer's entry point
    print(render(), end="")

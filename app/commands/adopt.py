"""``skisnow adopt``: give the uploads of no team to a team (token mode, docs/deployment.md).

Uploads made before team tokens were switched on (``SKISNOW_TEAM_TOKENS``) belong to no team:
once tokens are on, every team sees them and none may rename or delete them (403,
app/api/access.py). An operator assigns them, on the machine that holds the catalogue (the
same ``SKISNOW_DATA_DIR`` / ``SKISNOW_DATABASE_URL`` as the service):

    skisnow adopt --list                          # the uploads of no team
    skisnow adopt --team team-a my-grind my-ski   # these, by name
    skisnow adopt --team team-a --kind grind --all

The team must be one of the configured teams. Shipped demo items and items of a team are
never changed. A running service sees the new owner within ``job_poll_s``; from then on other
teams no longer see the item (404) and its team may change it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

#: the kinds of items (app.storage.catalogue.ITEM_KINDS; not imported: the CLI starts fast)
ITEM_KINDS = ("ski", "grind")


def register(sub: argparse._SubParsersAction) -> None:
    a = sub.add_parser("adopt", help="give uploads of no team to a team (token mode)")
    a.add_argument("names", nargs="*", metavar="NAME", help="items to give (names)")
    a.add_argument("--team", help="the team that gets them (one of SKISNOW_TEAM_TOKENS)")
    a.add_argument("--kind", choices=ITEM_KINDS, help="only items of this kind")
    a.add_argument("--all", action="store_true", help="every upload of no team")
    a.add_argument("--list", action="store_true", help="list the uploads of no team; change none")
    a.set_defaults(func=run)


def orphans(db, kind: str | None = None) -> list:
    """The uploads of no team (shipped items excluded), by kind and name."""
    return [r for r in db.items(kind) if r.team is None and not r.read_only]


def select(db, names: list[str], kind: str | None, every: bool) -> list:
    """The items to adopt; :class:`InputError` for a name that is unknown, ambiguous (a ski and
    a grind: give ``--kind``), shipped or of a team already."""
    from skisnow.solvers.errors import InputError

    if every:
        if names:
            raise InputError("give NAMEs or --all, not both")
        return orphans(db, kind)
    if not names:
        raise InputError("name the items to adopt, or give --all (see --list)")
    out = []
    for name in names:
        rows = [db.item_by_name(k, name) for k in ((kind,) if kind else ITEM_KINDS)]
        rows = [r for r in rows if r is not None]
        if not rows:
            raise InputError(f"no {kind or 'item'} named {name!r} in the catalogue")
        if len(rows) > 1:
            raise InputError(f"{name!r} is a ski and a grind: give --kind ski or --kind grind")
        row = rows[0]
        if row.read_only:
            raise InputError(f"{row.kind} {name!r} is a shipped demo item: it has no team")
        if row.team is not None:
            raise InputError(f"{row.kind} {name!r} belongs to team {row.team!r} already")
        out.append(row)
    return out


def run(args: argparse.Namespace) -> int:
    from skisnow.app.settings import Settings
    from skisnow.app.storage.catalogue import CatalogueDB
    from skisnow.solvers.errors import InputError

    settings = Settings()
    url = settings.catalogue_url
    if url.startswith("sqlite:///") and not Path(url.removeprefix("sqlite:///")).is_file():
        raise InputError(
            f"no catalogue at {url.removeprefix('sqlite:///')}: give the service's "
            "SKISNOW_DATA_DIR (or SKISNOW_DATABASE_URL)"
        )
    db = CatalogueDB(url)
    try:
        if args.list:
            rows = orphans(db, args.kind)
            for r in rows:
                print(
                    f"{r.kind}\t{r.name}\t{r.state}\t{r.created_at.isoformat(timespec='seconds')}"
                )
            if not rows:
                print("no uploads of no team")
            return 0
        teams = sorted(set(settings.team_tokens.values()))
        if not args.team:
            raise InputError(f"give --team (one of {teams or 'no configured team'})")
        if args.team not in teams:
            raise InputError(
                f"team {args.team!r} is not a configured team (SKISNOW_TEAM_TOKENS: "
                f"{', '.join(teams) or 'none configured'}): its items would be seen by nobody"
            )
        rows = select(db, args.names, args.kind, args.all)
        done = 0
        for row in rows:
            if db.adopt_item(row.id, args.team):
                print(f"{row.kind} {row.name}: now of team {args.team}")
                done += 1
            else:
                print(f"{row.kind} {row.name}: changed meanwhile, left as it is")
        print(f"{done} item(s) adopted by team {args.team}")
        return 0
    finally:
        db.close()

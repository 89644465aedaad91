"""Who gets a WebSocket slot: the pilot's seat is always reachable.

Every connection is accepted; when that would break a limit, other *viewers* are closed first
(the pilot's connection is never counted nor closed):

1. at most `max_per_address` viewers per address (an IPv4 address or IPv6 /64): the oldest
   viewer of the newcomer's own address is closed, so a stranger elsewhere never affects it;
2. at most `max_viewers` viewers in all: the oldest viewer of the address holding the most
   connections is closed.

So a page that brings the token gets a socket at once and authenticates before a flood from
other addresses can push it out: with every address at one connection, a newcomer is the
*last* to be closed (oldest first), which leaves it `max_viewers` reconnections of the flood to
send its `auth` (a few milliseconds on the boat's Wi-Fi).
"""

from __future__ import annotations

from collections import Counter
from typing import Protocol, Sequence, TypeVar


class Occupant(Protocol):
    address: str
    seq: int  # order of arrival

    @property
    def is_pilot(self) -> bool: ...


T = TypeVar("T", bound=Occupant)


def choose_evictions(occupants: Sequence[T], new_address: str, max_viewers: int,
                     max_per_address: int) -> list[tuple[T, str]]:
    """The viewers to close (with the reason) before a connection from `new_address` joins."""
    viewers = sorted((o for o in occupants if not o.is_pilot), key=lambda o: o.seq)
    out: list[tuple[T, str]] = []
    same = [o for o in viewers if o.address == new_address]
    while len(same) >= max_per_address:
        v = same.pop(0)
        viewers.remove(v)
        out.append((v, f"too many connections from your address (at most {max_per_address} viewers)"))
    while viewers and len(viewers) >= max_viewers:
        counts = Counter(o.address for o in viewers)
        top = max(counts.values())
        v = next(o for o in viewers if counts[o.address] == top)  # oldest of the busiest address
        viewers.remove(v)
        out.append((v, f"the boat's server is full ({max_viewers} viewers); a newer connection took the slot"))
    return out

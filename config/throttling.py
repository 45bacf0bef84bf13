"""Rate limits any app may use: the rate format (`parse_rate`), the client's address,
failed sign-ins per address and per name (`LoginAttempts`), and the limits on actions
that move a drone (commands, mission starts, teleoperation).

They live in config because several apps share them: fleet, missions and pastview count
drone-moving actions here, and a failed sign-in counts the same whether a person's
(accounts) or a drone's (logs/collect_api.py), and logs may not import accounts. The
people's own sign-in throttles, the token view's and the login page's, are accounts'
alone and live in accounts/throttling.py.

Counts live in Django's cache (Redis), so every web process shares them. The client is
its address as DRF tells it (the last NUM_PROXIES hops of X-Forwarded-For are trusted,
none by default, so a forged header changes nothing).
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

from django.conf import settings
from django.core.cache import cache
from django.http import HttpRequest
from rest_framework.throttling import BaseThrottle, SimpleRateThrottle

PERIODS_S = {"s": 1, "m": 60, "h": 3600, "d": 86400}


def parse_rate(rate: str) -> tuple[int, int]:
    """`10/min` → (10, 60): at most that many in that many seconds."""
    count, _, period = rate.partition("/")
    if not count.strip().isdigit() or period.strip()[:1] not in PERIODS_S:
        raise ValueError(f"a rate is like 10/min, not {rate!r}")
    return int(count), PERIODS_S[period.strip()[0]]


def client_address(request: HttpRequest) -> str:
    """The caller's address, as every DRF throttle sees it (NUM_PROXIES hops trusted)."""
    return BaseThrottle().get_ident(request)


class LoginAttempts:
    """Failed logins in the current LOGIN_RATE window, per client address and per
    username (a person's, or `drone:<id>` for a drone's): either one over the limit
    refuses further tries until the window ends."""

    def __init__(self, request: HttpRequest, username: str | None = None) -> None:
        self.limit, self.window_s = parse_rate(settings.LOGIN_RATE)
        if username is None:
            username = str(request.POST.get("username", ""))
        username = username.strip().lower()[:150]
        self.keys = [f"login-failures:ip:{client_address(request)}"]
        if username:
            self.keys.append(f"login-failures:user:{username}")

    def exhausted(self) -> bool:
        counts = cache.get_many(self.keys)
        return any(int(count) >= self.limit for count in counts.values())

    def failed(self) -> None:
        for key in self.keys:
            # add() starts the window only once; incr() is atomic in Redis.
            cache.add(key, 0, timeout=self.window_s)
            try:
                cache.incr(key)
            except ValueError:  # the window ended between the two calls
                cache.add(key, 1, timeout=self.window_s)


class ActionRateThrottle(SimpleRateThrottle):
    """`rate_setting` per caller on an action that moves a drone. `per` says whose count:
    the user's (whatever the credential), or the API token's (a session has none, so this
    one leaves it to the user's count). Counts live in the shared cache, so every web
    process sees the same ones; over the rate, DRF answers 429 with Retry-After."""

    rate_setting = ""
    per = "user"

    def get_rate(self) -> str:
        return getattr(settings, self.rate_setting)

    def get_cache_key(self, request, view) -> str | None:  # type: ignore[no-untyped-def]
        ident = caller(request, self.per)
        if ident is None:
            return None
        return f"throttle_{self.scope}_{self.per}_{ident}"


def caller(request: Any, per: str) -> str | None:
    """The user's id, or the token's kind and id; None when there is none to count."""
    if per == "user":
        user = getattr(request, "user", None)
        return str(user.pk) if user is not None and user.is_authenticated else None
    token = getattr(request, "auth", None)
    return f"{type(token).__name__}:{token.pk}" if getattr(token, "pk", None) else None


def action_throttles(scope: str, rate_setting: str) -> list[type[ActionRateThrottle]]:
    """A throttle per user and one per token for an action, for a view's throttle_classes."""
    return [
        type(
            f"{scope.title()}{per.title()}Throttle",
            (ActionRateThrottle,),
            {"scope": scope, "rate_setting": rate_setting, "per": per},
        )
        for per in ("user", "token")
    ]


COMMAND_THROTTLES = action_throttles("command", "COMMAND_RATE")
MISSION_START_THROTTLES = action_throttles("mission_start", "MISSION_START_RATE")


class TeleopRate:
    """TELEOP_RATE for one user's teleoperation input over the past-view socket (the
    same counts as ActionRateThrottle, keyed by user): `wait_s` is None while under it."""

    def __init__(self, user: Any) -> None:
        self.throttle = action_throttles("teleop", "TELEOP_RATE")[0]()
        self.request = _Caller(user)

    def wait_s(self) -> float | None:
        if self.throttle.allow_request(self.request, None):
            return None
        return self.throttle.wait() or 0.0


class _Caller:
    def __init__(self, user: Any) -> None:
        self.user = user
        self.auth = None


class _OneRequestsCounts:
    """The cache as the throttles of one request see it: the counts read for all of them
    at once, and their writes kept to be written at once (`write`)."""

    def __init__(self, keys: list[str]) -> None:
        self.values = cache.get_many(keys) if keys else {}
        self.writes: dict[Any, dict[str, Any]] = defaultdict(dict)

    def get(self, key: str, default: Any = None) -> Any:
        return self.values.get(key, default)

    def set(self, key: str, value: Any, timeout: Any = None) -> None:
        self.values[key] = value
        self.writes[timeout][key] = value

    def write(self) -> None:
        for timeout, values in self.writes.items():
            cache.set_many(values, timeout)


class TogetherThrottles:
    """For an APIView: its rate throttles that count in the shared cache read their counts
    in one round trip and write them in one, rather than two each; each throttle decides
    by its own `allow_request` as DRF would have it."""

    def check_throttles(self, request: Any) -> None:
        throttles = self.get_throttles()  # type: ignore[attr-defined]
        shared = [
            t
            for t in throttles
            if isinstance(t, SimpleRateThrottle) and t.cache is cache and t.rate is not None
        ]
        keys = [k for t in shared if (k := t.get_cache_key(request, self)) is not None]
        counts = _OneRequestsCounts(keys)
        for throttle in shared:
            throttle.cache = counts
        waits = [t.wait() for t in throttles if not t.allow_request(request, self)]
        counts.write()
        if waits:
            # As DRF's APIView.check_throttles: the longest wait any of them names.
            self.throttled(request, max((w for w in waits if w is not None), default=None))  # type: ignore[attr-defined]

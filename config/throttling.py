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

import functools
import os
import time
from typing import Any

import redis
from django.conf import settings
from django.core.cache import cache
from django.http import HttpRequest
from redis.commands.core import Script
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
    one leaves it to the user's count). Over the rate, DRF answers 429 with Retry-After.

    The window is DRF's sliding one (a request counts while it is younger than the period)
    and `wait` is DRF's, but the requests of the window are a sorted set in Redis, trimmed,
    counted and added to by one script (`count_in_windows`): one round trip for all of a
    request's throttles, and two web processes cannot both take the last place in a
    window, as they could between DRF's read and write of a cached list."""

    rate_setting = ""
    per = "user"
    count = 0
    oldest: float | None = None

    def get_rate(self) -> str:
        return getattr(settings, self.rate_setting)

    def get_cache_key(self, request, view) -> str | None:  # type: ignore[no-untyped-def]
        ident = caller(request, self.per)
        if ident is None:
            return None
        return f"rate:{self.scope}:{self.per}:{ident}"

    def allow_request(self, request, view) -> bool:  # type: ignore[no-untyped-def]
        key = None if self.rate is None else self.get_cache_key(request, view)
        return key is None or count_in_windows([(self, key)])[0]

    def wait(self) -> float | None:
        """DRF's: the time until the oldest request leaves the window, shared among the
        places that will then be free."""
        since_oldest = 0.0 if self.oldest is None else self.now - self.oldest
        available = self.num_requests - self.count + 1
        if available <= 0:
            return None
        return (self.duration - since_oldest) / available


# KEYS: one sorted set per throttle. ARGV: the time (s), this request's member, then each
# key's limit and window (s). Each key is trimmed to its window and counted; a key under
# its limit takes the request, as each DRF throttle records a request it lets through.
_WINDOWS_SCRIPT = """
local now = tonumber(ARGV[1])
local answers = {}
for i, key in ipairs(KEYS) do
  local limit = tonumber(ARGV[1 + 2 * i])
  local window = tonumber(ARGV[2 + 2 * i])
  redis.call('ZREMRANGEBYSCORE', key, '-inf', now - window)
  local count = redis.call('ZCARD', key)
  local oldest = redis.call('ZRANGE', key, 0, 0, 'WITHSCORES')[2] or ''
  local allowed = 0
  if count < limit then
    redis.call('ZADD', key, now, ARGV[2])
    redis.call('EXPIRE', key, window)
    allowed = 1
  end
  answers[i] = {allowed, count, oldest}
end
return answers
"""


@functools.cache
def _windows(pool: redis.ConnectionPool) -> Script:
    """The script, on a client of the cache's pool kept for the process: Django's cache
    builds a new client for every call, a tenth of a millisecond of CPU each."""
    return redis.Redis(connection_pool=pool).register_script(_WINDOWS_SCRIPT)


def count_in_windows(throttles: list[tuple[ActionRateThrottle, str]]) -> list[bool]:
    """Whether each throttle lets the request through, all decided in one Redis round
    trip; each throttle keeps its count and oldest request for its `wait`."""
    script = _windows(cache._cache._get_connection_pool(True))  # type: ignore[attr-defined]
    now = time.time()
    args: list[Any] = [repr(now), f"{now!r}:{os.urandom(6).hex()}"]
    for throttle, _ in throttles:
        args += [throttle.num_requests, throttle.duration]
    keys = [cache.make_key(key) for _, key in throttles]
    answers = script(keys=keys, args=args)
    for (throttle, _), (_, count, oldest) in zip(throttles, answers, strict=True):
        throttle.now, throttle.count = now, int(count)
        throttle.oldest = float(oldest) if oldest else None
    return [bool(allowed) for allowed, _, _ in answers]


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


class TogetherThrottles:
    """For an APIView: its window throttles decide in one Redis round trip
    (`count_in_windows`) rather than one each; any other throttle decides by its own
    `allow_request`, and the answer is DRF's."""

    def check_throttles(self, request: Any) -> None:
        windows, waits = [], []
        for throttle in self.get_throttles():  # type: ignore[attr-defined]
            if isinstance(throttle, ActionRateThrottle) and throttle.rate is not None:
                key = throttle.get_cache_key(request, self)
                if key is not None:
                    windows.append((throttle, key))
            elif not throttle.allow_request(request, self):
                waits.append(throttle.wait())
        if windows:
            allowed = count_in_windows(windows)
            waits += [t.wait() for (t, _), ok in zip(windows, allowed, strict=True) if not ok]
        if waits:
            # As DRF's APIView.check_throttles: the longest wait any of them names.
            self.throttled(request, max((w for w in waits if w is not None), default=None))  # type: ignore[attr-defined]

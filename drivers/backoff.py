"""The reconnect back-off of every device: the first and the largest wait between attempts.

A device that goes away is retried with waits that double from the first to the largest. A first
wait of 0 would make the retry loop spin while the device is missing, so both devices' settings
refuse it here, in the one check they share.
"""

from __future__ import annotations


def check_backoff(backoff: tuple[float, float]) -> None:
    """Raise ``ValueError`` unless ``0 < first <= largest``."""
    first, largest = backoff
    if not 0.0 < first <= largest:
        raise ValueError(
            f"reconnect_backoff: expected 0 < first <= largest, got [{first}, {largest}]"
        )

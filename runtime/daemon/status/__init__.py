"""What a running daemon says about itself: its rates, CPU and peers (:mod:`.health`) and what
is wrong, in words (:mod:`.faults`), put together in the ``percept.status/1`` message."""

"""collector_paused: the cyclic garbage collector off inside the block, as it was after."""

from __future__ import annotations

import gc

import pytest

from bfsitl.collector_paused import collector_paused


def test_the_collector_is_off_inside_and_on_again_after_even_when_the_block_raises() -> None:
    assert gc.isenabled()
    with collector_paused():
        assert not gc.isenabled()
    assert gc.isenabled()
    with pytest.raises(RuntimeError), collector_paused():
        raise RuntimeError("boom")
    assert gc.isenabled()


def test_a_block_inside_another_or_a_caller_that_turned_it_off_keeps_it_off() -> None:
    with collector_paused():
        with collector_paused():
            pass
        assert not gc.isenabled()  # the inner block must not turn it on for the outer
    gc.disable()
    try:
        with collector_paused():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()

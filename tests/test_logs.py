"""Logging levels of hwsim and the libraries (hwsim.core.logs): quiet unless verbose."""

from __future__ import annotations

import logging

import pytest

from hwsim.core import logs


@pytest.fixture(autouse=True)
def restore_logging():
    """Put every logger's level, filters and the root's handlers back afterwards."""
    names = [None, *logs.OWN, *logs.LIBRARIES, *(name for name, _, _ in logs.BENIGN)]
    saved = [
        (logging.getLogger(n), logging.getLogger(n).level, list(logging.getLogger(n).filters))
        for n in names
    ]
    handlers = list(logging.getLogger().handlers)
    state = dict(logs._state)
    yield
    for logger, level, filters in saved:
        logger.setLevel(level)
        logger.filters[:] = filters
    logging.getLogger().handlers[:] = handlers
    logs._state.update(state)


def heartbeat_record(error: BaseException) -> logging.LogRecord:
    try:
        raise error
    except type(error):
        import sys

        exc_info = sys.exc_info()
    return logging.getLogger("distributed.worker").makeRecord(
        "distributed.worker",
        logging.ERROR,
        __file__,
        1,
        "Failed to communicate with scheduler during heartbeat.",
        (),
        exc_info,
    )


class CommClosedError(OSError):
    """Stands in for distributed.comm.core.CommClosedError (matched by name)."""


def test_by_default_hwsim_warns_and_the_libraries_speak_only_of_errors():
    logs.configure_logging(0)
    assert logging.getLogger("hwsim.run").getEffectiveLevel() == logging.WARNING
    for name in ("distributed.worker", "numba.core", "asyncio", "matplotlib", "PIL", "simpy"):
        assert logging.getLogger(name).getEffectiveLevel() == logging.ERROR, name
    assert logs.verbosity() == 0


@pytest.mark.parametrize(("verbose", "level"), [(1, logging.INFO), (2, logging.DEBUG)])
def test_verbose_turns_on_info_then_debug_for_hwsim_and_the_libraries(verbose, level):
    logs.configure_logging(verbose)
    for name in ("hwsim", "models.cycle", "distributed.scheduler", "numba", "amaranth"):
        assert logging.getLogger(name).getEffectiveLevel() == level, name
    assert logs.verbosity() == verbose


def test_a_heartbeat_meeting_a_closed_scheduler_is_dropped_other_errors_are_not():
    worker = logging.getLogger("distributed.worker")
    logs.configure_logging(0)
    assert not worker.filter(heartbeat_record(CommClosedError("in: closed")))
    assert worker.filter(heartbeat_record(ValueError("a real fault")))
    logs.configure_logging(1)  # verbose: nothing is dropped
    assert worker.filter(heartbeat_record(CommClosedError("in: closed")))


def test_configuring_twice_adds_one_handler_and_follows_stderr(capsys):
    logs.configure_logging(0)
    logs.configure_logging(0)
    ours = [h for h in logging.getLogger().handlers if isinstance(h, logs._Stderr)]
    assert len(ours) == 1
    logging.getLogger("hwsim.test").warning("seen")
    logging.getLogger("hwsim.test").info("not seen")
    assert capsys.readouterr().err == "hwsim.test WARNING: seen\n"


def test_a_library_user_is_left_alone_until_the_command_line_configures():
    logs._state.update(verbosity=0, configured=False)
    logging.getLogger("distributed").setLevel(logging.INFO)
    logs.reapply()
    assert logging.getLogger("distributed").level == logging.INFO

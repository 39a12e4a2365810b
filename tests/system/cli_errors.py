"""What every bad-input test of the CLI checks: one ``hwsim: error:`` line on stderr."""


def one_line_error(capsys, *fragments: str) -> str:
    """stderr of the run just made, asserted to be one ``hwsim: error:`` line holding
    every fragment (the file, the key, the allowed range)."""
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("hwsim: error: "), err
    for fragment in fragments:
        assert fragment in err, err
    return err

"""What is measured over many runs: published figures, the speed bench, RTL diffs,
sweeps and the ladder trade."""

"""The progress bar of long runs (tqdm on a terminal), shared by every loop that
runs long: particle steps, peridynamic steps, RVE tests and macroscale load steps."""


def progress_bar(n_steps, progress, min_steps=20000, unit="step"):
    """A tqdm bar over ``n_steps``, or None. ``progress`` True/False forces it; None
    shows it when stderr is a terminal and there are at least ``min_steps``."""
    import sys

    if progress is None:
        progress = n_steps >= min_steps and sys.stderr.isatty()
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=n_steps, unit=unit, unit_scale=min_steps > 1, leave=False)

"""matplotlib for the demos' pictures (no pybullet here: the solver's demo needs none)."""


def pyplot():
    """matplotlib.pyplot on the headless Agg backend, or a one-line exit without it."""
    try:
        import matplotlib
    except ImportError:
        raise SystemExit("this demo draws its picture with matplotlib, which is not installed: pip install "
                         "matplotlib (pip install . from the bullet_boxccd checkout installs it)") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt

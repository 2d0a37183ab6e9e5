"""``python -m srpb_gym``: the ``srpb-gym`` command line."""

from srpb_gym.cli import main

if __name__ == "__main__":
    raise SystemExit(main())

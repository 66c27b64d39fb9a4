"""``python -m mlink_sim`` == ``mlink-sim``."""

from .cli import main

if __name__ == "__main__":
    main()

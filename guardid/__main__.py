"""Allow ``python -m guardid``."""

from guardid.cli import main

if __name__ == "__main__":
    main()

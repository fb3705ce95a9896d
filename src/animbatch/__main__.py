"""``python -m animbatch``: the same as the ``animbatch`` command."""

from animbatch.cli import main

if __name__ == "__main__":
    main()

"""Allow ``python -m viscorig``."""

from viscorig.cli import main

raise SystemExit(main())

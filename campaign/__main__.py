"""`python -m campaign` is the same as the `axiscal` command."""

from campaign.cli import main

raise SystemExit(main())

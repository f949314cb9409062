from repertoire.cli import main

raise SystemExit(main())

"""A minimal GTP engine for tests: ``python fake_gtp.py MODE``.

Answers every command with success. ``genmove``/``kgs-genmove_cleanup``:

* ``resign``: resigns at once;
* ``pass``: passes;
* ``resign-after:N``: passes N times, then resigns;
* ``die-once:FILE``: at the first genmove, if FILE does not exist, creates it
  and exits without answering (a crash); otherwise passes;
* ``hang-once:FILE``: the same, but stops answering instead of exiting.

It keeps no board (the environment checks legality; a pass is always legal).
"""

import os
import re
import sys
import time


def main() -> None:
    mode = sys.argv[1] if len(sys.argv) > 1 else "pass"
    passes_left = int(mode.split(":", 1)[1]) if mode.startswith("resign-after:") else None
    for line in sys.stdin:
        line = line.strip()
        if not line:
            continue
        match = re.match(r"^(\d+)\s+(.*)$", line)
        cmd_id, body = (match.group(1), match.group(2)) if match else ("", line)
        name = body.split()[0].lower()
        reply = ""
        if name in ("genmove", "kgs-genmove_cleanup"):
            kind, _, marker = mode.partition(":")
            if kind in ("die-once", "hang-once") and not os.path.exists(marker):
                open(marker, "w").close()
                if kind == "die-once":
                    sys.exit(3)
                time.sleep(3600)
            if mode == "resign":
                reply = "resign"
            elif passes_left is not None:
                reply = "pass" if passes_left > 0 else "resign"
                passes_left -= 1
            else:
                reply = "pass"
        sys.stdout.write(f"={cmd_id} {reply}".rstrip() + "\n\n")
        sys.stdout.flush()
        if name == "quit":
            return


if __name__ == "__main__":
    main()

"""A Ray worker set-up hook for the retry test: the first try of shard 0 kills its worker
process, as a lost node would (the marker file in $CRASH_ONCE_DIR remembers it happened)."""

import os


def install() -> None:
    import mimicgen_rs.ray as mgray

    original = mgray._run_shard

    def run_shard(part, count, kwargs):
        marker = os.path.join(os.environ["CRASH_ONCE_DIR"], "crashed_once")
        if part == 0 and not os.path.exists(marker):
            open(marker, "w").close()
            os._exit(1)
        return original(part, count, kwargs)

    mgray._run_shard = run_shard

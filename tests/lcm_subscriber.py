"""A separate-process LCM subscriber for the publisher tests: writes one JSON line per message to a
file (not to a pipe, whose buffer would fill and block it), prints "ready" once subscribed, and
stops once a message has arrived on ``<channel>_done`` (sent by the test after its run) and the
messages already received are handled, or after ``timeout`` seconds if that never comes.

    python lcm_subscriber.py CHANNEL state|scope TIMEOUT_S OUT.jsonl
"""

import json
import sys
import time

from drake import lcmt_robot_state, lcmt_scope
from pydrake.lcm import DrakeLcm

channel, kind, timeout, path = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
decode = {"state": lcmt_robot_state.decode, "scope": lcmt_scope.decode}[kind]
lcm = DrakeLcm()
out = open(path, "w")
done = False


def handle(data: bytes) -> None:
    message = decode(data)
    values = list(message.joint_position) if kind == "state" else list(message.value)
    names = list(message.joint_name) if kind == "state" else []
    out.write(json.dumps({"utime": message.utime, "values": values, "names": names[:8]}) + "\n")


def finish(data: bytes) -> None:
    global done
    done = True


lcm.Subscribe(channel, handle)
lcm.Subscribe(channel + "_done", finish)
print("ready", flush=True)
end = time.monotonic() + timeout
while not done and time.monotonic() < end:
    lcm.HandleSubscriptions(20)
while done and lcm.HandleSubscriptions(50) > 0:  # whatever is still queued
    pass
out.close()
sys.exit(0 if done else 1)

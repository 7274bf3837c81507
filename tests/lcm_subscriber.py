"""A separate-process LCM subscriber for the publisher tests: writes one JSON line per message to a
file (not to a pipe, whose buffer would fill and block it), prints "ready" once subscribed."""

import json
import sys
import time

from drake import lcmt_robot_state, lcmt_scope
from pydrake.lcm import DrakeLcm

channel, kind, seconds, path = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
decode = {"state": lcmt_robot_state.decode, "scope": lcmt_scope.decode}[kind]
lcm = DrakeLcm()
out = open(path, "w")


def handle(data: bytes) -> None:
    message = decode(data)
    values = list(message.joint_position) if kind == "state" else list(message.value)
    names = list(message.joint_name) if kind == "state" else []
    out.write(json.dumps({"utime": message.utime, "values": values, "names": names[:8]}) + "\n")


lcm.Subscribe(channel, handle)
print("ready", flush=True)
end = time.monotonic() + seconds
while time.monotonic() < end:
    lcm.HandleSubscriptions(20)
out.close()

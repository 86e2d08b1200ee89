"""Run by test_fmu_state.py in a subprocess, one per FMU: damage a serialized FMU state in every
aligned field (and at random) and hand it to the FMU through FMPy, which must answer every time.

usage: python fmu_state_fuzz.py FMU KIND VERSION UNZIP_DIR; prints a JSON summary. A crash of
the FMU ends this process, which the test sees as a failure."""
import ctypes
import json
import random
import struct
import sys

import fmpy
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave

#: Bit patterns written over each aligned 8-byte field, and over each 4-byte field (the method
#: and flag ints).
DOUBLES = [float("nan"), float("inf"), -1e300, 1e6, -1.0, 0.5, 2.0, 0.0]
INTS = [10**6, -2**31, 7, 5, 2, -1, 2**31 - 1]


def fnv1a(data):
    """FNV-1a (64 bits), the checksum fmu_core.c.in writes after the values."""
    h = 14695981039346656037
    for b in data:
        h = ((h ^ b) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return h


def instance(path, kind, version, unzipped):
    md = fmpy.read_model_description(path)
    interface = md.coSimulation if kind == "cs" else md.modelExchange
    cls = {("cs", 2): FMU2Slave, ("me", 2): FMU2Model, ("cs", 3): FMU3Slave,
           ("me", 3): FMU3Model}[kind, version]
    guid = md.guid if version == 2 else md.instantiationToken
    fmu = cls(guid=guid, unzipDirectory=unzipped, modelIdentifier=interface.modelIdentifier,
              instanceName="fuzz")
    fmu.instantiate()
    if version == 2:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([0], [0.3])
    else:
        fmu.enterInitializationMode(startTime=0.0)
        fmu.setFloat64([0], [0.3])
    fmu.exitInitializationMode()
    if kind == "me":
        fmu.enterContinuousTimeMode()
    return md, fmu, guid


def main(path, kind, version, unzipped):
    version = int(version)
    md, fmu, guid = instance(path, kind, version, unzipped)
    nx = sum(1 for v in md.modelVariables if v.derivative is not None)
    get_state = fmu.getFMUState
    deserialize = fmu.deSerializeFMUstate if version == 2 else fmu.deserializeFMUState
    if kind == "cs":
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.05)
    good = bytes(fmu.serializeFMUState(get_state()))
    start = -(-(len(guid) + 1) // 8) * 8          # the values, after the token
    end = len(good) - 8                           # then the checksum
    n_params = sum(1 for v in md.modelVariables if v.causality == "parameter"
                   and not v.name.startswith("solver."))
    n_inputs = sum(1 for v in md.modelVariables if v.causality == "input")
    rtol = start + 8 * (1 + nx + max(n_params, 1) + max(n_inputs, 1))
    method = rtol + 8 * 2
    summary = {"size": len(good), "raw": 0, "raw_refused": 0, "signed": 0,
               "signed_refused": 0, "nan_accepted": [], "int_accepted": [], "rtol_accepted": [],
               "accepted_then_ok": 0,
               "accepted_then_error": 0, "random": 0, "random_refused": 0}

    def try_state(blob):
        """True when the FMU refused the state; else the state is set and used."""
        try:
            state = deserialize(blob)
        except Exception:
            return True
        try:
            fmu.setFMUState(state)
            if kind == "cs":
                fmu.doStep(currentCommunicationPoint=restored_time(blob),
                           communicationStepSize=0.01)
            elif version == 2:
                fmu.getDerivatives((ctypes.c_double * nx)(), nx)
            else:
                fmu.getContinuousStateDerivatives((ctypes.c_double * nx)(), nx)
            summary["accepted_then_ok"] += 1
        except Exception:
            summary["accepted_then_error"] += 1
        finally:
            fmu.freeFMUState(state)
        return False

    def restored_time(blob):
        return struct.unpack_from("<d", blob, start)[0]

    def signed(blob):
        out = bytearray(blob)
        struct.pack_into("<Q", out, end, fnv1a(bytes(out[start:end])))
        return bytes(out)

    for offset in range(0, len(good) - 7, 4):
        patterns = [struct.pack("<i", v) for v in INTS]
        if offset % 8 == 0:
            patterns += [struct.pack("<d", v) for v in DOUBLES]
        for pattern in patterns:
            blob = bytearray(good)
            blob[offset:offset + len(pattern)] = pattern
            blob = bytes(blob)
            if blob == good:
                continue
            summary["raw"] += 1
            summary["raw_refused"] += try_state(blob)
            if start <= offset < end:
                summary["signed"] += 1
                refused = try_state(signed(blob))
                summary["signed_refused"] += refused
                if pattern == struct.pack("<d", float("nan")) and not refused:
                    summary["nan_accepted"].append(offset)
                if offset == rtol and len(pattern) == 8 and not refused:
                    summary["rtol_accepted"].append(struct.unpack("<d", pattern)[0])
                if offset in (method, method + 4) and len(pattern) == 4 and not refused:
                    summary["int_accepted"].append(
                        ["method" if offset == method else "terminated",
                         struct.unpack("<i", pattern)[0]])
    rng = random.Random(1)
    for _ in range(200):
        blob = bytearray(good)
        for _ in range(rng.randint(1, 8)):
            blob[rng.randrange(start, end)] = rng.randrange(256)
        summary["random"] += 1
        summary["random_refused"] += try_state(bytes(blob))
        try_state(signed(blob))
    summary["good_accepted"] = not try_state(good)
    if kind == "cs":
        summary["steps"] = bad_steps(fmu, deserialize(good), restored_time(good))
    print(json.dumps(summary))


def bad_steps(fmu, state, t):
    """{call: refused} for communication steps no engine can take: a NaN communication point,
    a step of 1e300 (more steps than an FMU step may take, never memory that grows with h)."""
    out = {}
    for name, point, size in (("nan_point", float("nan"), 0.1), ("huge_step", t, 1e300),
                              ("nan_step", t, float("nan"))):
        fmu.setFMUState(state)
        try:
            fmu.doStep(currentCommunicationPoint=point, communicationStepSize=size)
            out[name] = False
        except Exception:
            out[name] = True
    return out


if __name__ == "__main__":
    main(*sys.argv[1:])

#!/usr/bin/python3
"""A capillary-number sweep of a cell in shear flow, run as one study through
the cellflow service and drawn with matplotlib: D(strain) of each point and
the steady D against Ca beside Roscoe's small-deformation 5/4 Ca.

    export CELLFLOW_SERVER=127.0.0.1:50051           # and CELLFLOW_TOKEN, as for the CLI
    PYTHONPATH=build/python /usr/bin/python3 examples/python/sweep_and_plot.py -o sweep.png
    ... --ca 0.05,0.1,0.2 --spec examples/shear_flow.json   # the defaults
    ... --quick                                       # tiny numerics: seconds, not minutes
    ... --separate                                    # one job per point instead of a study
"""

import argparse
import json
import pathlib
import sys

import cellflow

CHECKOUT = pathlib.Path(__file__).resolve().parents[2]
AXIS = "shearFlow.capillaryNumber"


def quick(spec):
    """The tiny numerics of the tests: 3 nodes per radius, 300 vertices, 2 strain units."""
    flow = spec["shearFlow"]
    flow["cell"]["targetVertexCount"] = 300
    flow["numerics"] = {"cellsPerRadius": 3, "boxXRadii": 5, "boxYRadii": 6, "boxZRadii": 4, "maxStrain": 2,
                        "sampleEveryStrain": 0.1, "snapshotEveryStrain": 1}
    return spec


def run_study(client, base, values):
    study = client.submit_study(base, {AXIS: values}, name=f"Ca sweep {values}")
    print(f"study {study.id}: {len(values)} points")
    for event in client.watch(study.id):
        if isinstance(event, cellflow.ChildUpdate):
            print(f"  point {event.child_index} ({event.child_job_id}): {event.state} {event.reason}".rstrip())
        elif isinstance(event, cellflow.StateChange) and event.terminal:
            print(f"study {study.id}: {event.state} {event.reason}".rstrip())
    return [child.id for child in client.children(study.id)]


def run_separate(client, base, values):
    ids = []
    for value in values:
        spec = json.loads(json.dumps(base))
        spec["shearFlow"]["capillaryNumber"] = value
        ids.append(client.submit(spec, name=f"Ca = {value}").id)
    for job_id in ids:
        print(f"  {job_id}: {cellflow.state_name(client.wait(job_id))}")
    return ids


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spec", default=str(CHECKOUT / "examples" / "shear_flow.json"), help="base shear-flow spec")
    parser.add_argument("--ca", default="0.05,0.1,0.2", help="capillary numbers, comma separated")
    parser.add_argument("--server", help="host:port (default CELLFLOW_SERVER)")
    parser.add_argument("--quick", action="store_true", help="tiny numerics (a few seconds per point)")
    parser.add_argument("--separate", action="store_true", help="submit one job per point, not a study")
    parser.add_argument("-o", "--output", default="sweep.png", help="the figure (png, svg, pdf)")
    args = parser.parse_args(argv)

    values = [float(v) for v in args.ca.split(",") if v.strip()]
    base = json.loads(pathlib.Path(args.spec).read_text())
    if "shearFlow" not in base:
        parser.error(f"{args.spec}: not a shear-flow spec")
    if args.quick:
        base = quick(base)
    base["shearFlow"]["numerics"]["fluidSnapshots"] = False  # the plot needs the time series only

    with cellflow.Client(args.server) as client:
        ids = run_separate(client, base, values) if args.separate else run_study(client, base, values)
        results = [client.result(job_id) for job_id in ids]

    import matplotlib

    matplotlib.use("Agg")  # a file, no display
    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    # The worker's steady D (/summary); a run stopped by maxStrain before
    # reaching steady state is drawn open, as `cellflow plot --against capillary-number` does.
    steady, reached = [], []
    for value, result in zip(values, results):
        left.plot(result["strain"], result["taylor_deformation"], label=f"Ca = {value:g}")
        steady.append(result.summary["steady_taylor_deformation"])
        reached.append(result.summary.get("stop") == "steady")
    left.set_xlabel("strain $\\dot\\gamma t$")
    left.set_ylabel("Taylor deformation D")
    left.legend()
    right.plot(values, steady, "-", color="C0")
    right.scatter(values, steady, facecolors=["C0" if r else "none" for r in reached], edgecolors="C0",
                  label="cellflow (open: not steady)", zorder=3)
    right.plot(values, [1.25 * v for v in values], "k--", label="Roscoe 5/4 Ca")
    right.set_xlabel("capillary number Ca")
    right.set_ylabel("steady D")
    right.legend()
    figure.tight_layout()
    figure.savefig(args.output)
    for value, d, r in zip(values, steady, reached):
        print(f"Ca {value:g}: steady D {d:.4f} (5/4 Ca = {1.25 * value:.4f}){'' if r else ', not steady'}")
    print(f"figure: {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""The gissar mission on the bundled Andorra data, end to end, from Python.

    scene -> SAR images at two headings -> matches -> F -> heading change (KvD) -> pose fix

Walked through in docs/tutorial.md. Run from the repository root after `make build`:

    PYTHONPATH=build/python /usr/bin/python3 examples/tutorial.py            # pictures in out/tutorial/
    PYTHONPATH=build/python /usr/bin/python3 examples/tutorial.py --out DIR
    PYTHONPATH=build/python /usr/bin/python3 examples/tutorial.py --temp     # a temporary directory (the smoke test)

Every step prints what it found; the script exits non-zero when a picture is missing or a result is off
(heading change off by more than 0.5 deg, pose fix not better than the INS prior).
"""
import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

import gissar

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "data", "andorra")

# The mission. Two passes over Andorra la Vella at 40 deg depression, 10 km slant range:
# pass 1 flies north (heading 0), pass 2 north-north-east (30 deg); pixels 30 m. The INS of pass 2 has drifted:
# it reports heading 31.5 deg and a sensor position 150 m east, 120 m south and 40 m above the truth.
DEPRESSION_DEG = 40.0
SLANT_RANGE_M = 10000.0
SPACING_M = 30.0
SIZE_PX = 320                       # square images (9.6 km), scene centre at the image centre
HEADINGS_DEG = (0.0, 30.0)
INS_HEADING_ERROR_DEG = 1.5
INS_POSITION_ERROR_M = np.array([150.0, -120.0, 40.0])
DEM_WINDOW = (150, 70, 180, 160)    # col, row, cols, rows of the 480 x 300 SRTM3 DEM: ~12 x 15 km


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default=os.path.join(ROOT, "out", "tutorial"), help="output directory")
    parser.add_argument("--temp", action="store_true", help="write into a temporary directory, removed at the end")
    args = parser.parse_args()
    if args.temp:
        with tempfile.TemporaryDirectory(prefix="gissar_tutorial_") as out:
            return run(out)
    os.makedirs(args.out, exist_ok=True)
    return run(args.out)


def run(out):
    start = time.time()
    pictures = []

    def say(text):
        print(f"[{time.time() - start:5.1f} s] {text}", flush=True)

    def save(name, image):
        path = os.path.join(out, name)
        gissar.write_png(path, image)
        pictures.append(path)
        return path

    # 1. The scene: DEM + OpenStreetMap layers -> classified constrained Delaunay mesh. The build writes
    #    the class map with its legend (_classes.png), a 3-D view (_3d.png) and, asked for, OBJ + MTL.
    scene = gissar.Scene.build(dem=os.path.join(DATA, "andorra_srtm3_dem_filled.tif"),
                               vectors=[os.path.join(DATA, "andorra_osm.gpkg")], window=DEM_WINDOW,
                               out_prefix=os.path.join(out, "andorra"), export_obj=True)
    pictures += [os.path.join(out, f) for f in ("andorra_classes.png", "andorra_3d.png", "andorra.obj")]
    counts = {name: int((scene.classes == i).sum()) for i, name in enumerate(scene.class_names)}
    say(f"scene: {len(scene.triangles)} triangles, per class {counts}")
    # The same pictures as arrays, e.g. a 3-D view from the south-east, seen like the radar of pass 1.
    save("andorra_3d_from_east.png", scene.view_3d(view_azimuth_deg=100, view_elevation_deg=40, width=720, height=480))

    # 2. SAR images at two headings (4-look speckle), with their geometry.
    sims = []
    for k, heading in enumerate(HEADINGS_DEG):
        sim = scene.simulate(heading_deg=heading, depression_deg=DEPRESSION_DEG, slant_range_m=SLANT_RANGE_M,
                             range_spacing_m=SPACING_M, azimuth_spacing_m=SPACING_M, width=SIZE_PX,
                             height=SIZE_PX, speckle_looks=4, seed=k + 1)
        g = sim.gissar.geometry  # sim: xarray.DataArray (band, along_track_m, slant_range_m)
        save(f"sar_h{heading:03.0f}_quicklook.png",
             gissar.annotated_quicklook(sim, g.range_spacing_m, g.azimuth_spacing_m,
                                        f"Andorra, heading {heading:.0f} deg, depression {DEPRESSION_DEG:.0f} deg",
                                        near_range_m=g.slant_range_m - g.u0 * g.range_spacing_m,
                                        azimuth_origin_m=-g.v0 * g.azimuth_spacing_m))
        say(f"image at heading {heading:.0f} deg: {sim.sizes['slant_range_m']} x {sim.sizes['along_track_m']} px, "
            f"layover {float(sim['layover'].mean()):.1%}, shadow {float(sim['shadow'].mean()):.1%}")
        sims.append(sim)
    # The sensor flying round the scene centre from heading 0 to 30 deg, as an animated GIF.
    paths = gissar.sequence(os.path.join(out, "sequence"), HEADINGS_DEG[0], HEADINGS_DEG[1], frames=4,
                            frame_delay_cs=60, scene=scene.path, depression_deg=DEPRESSION_DEG,
                            slant_range_m=SLANT_RANGE_M, range_spacing_m=2 * SPACING_M,
                            azimuth_spacing_m=2 * SPACING_M)
    pictures += [p for p in paths if p.endswith((".gif", "_contact.png"))]
    say(f"heading sequence: {os.path.basename(paths[-2])}")

    # 3. Matches. The INS predicts where a pixel of image 1 lands in image 2 (plane through the scene
    #    centre, reported heading 31.5 deg): image 2 is resampled onto image 1 with that affine map and
    #    matched by dense NCC of log intensities; the residual shifts are the relief parallax.
    g1, g2 = sims[0].gissar.geometry, sims[1].gissar.geometry
    ins2 = gissar.SarGeometry(heading_deg=HEADINGS_DEG[1] + INS_HEADING_ERROR_DEG, depression_deg=DEPRESSION_DEG,
                              range_spacing_m=SPACING_M, azimuth_spacing_m=SPACING_M,
                              slant_range_m=SLANT_RANGE_M, scene_centre_enu_m=g2.scene_centre_enu_m,
                              u0=g2.u0, v0=g2.v0, width=g2.width, height=g2.height)
    plane = np.array(g1.scene_centre_enu_m) + np.array([[0.0, 0, 0], [1000, 0, 0], [0, 1000, 0]])
    p1, p2 = g1.project(plane), ins2.project(plane)
    predicted = np.linalg.solve(np.column_stack([p1, np.ones(3)]), p2).T  # (2, 3): pixel 1 -> pixel 2
    m = gissar.match_images(sims[0], sims[1], warp=predicted, search_px=16, step_px=10)
    x1, x2 = m["x_reference"], m["x_observed"]
    # Saved for the command line (`gissar fmatrix --matches`, `gissar register --points`).
    np.savetxt(os.path.join(out, "matches.csv"), np.column_stack([x1, x2]), delimiter=",", fmt="%.4f",
               header="x1,y1,x2,y2", comments="")
    say(f"matches: {len(x1)}")

    # 4. F (RANSAC + Gold Standard) and its Koenderink-van Doorn reading: the heading change.
    f = gissar.fmatrix(x1, x2, range_spacing_m=(SPACING_M, SPACING_M), azimuth_spacing_m=(SPACING_M, SPACING_M),
                       depressions_deg=(DEPRESSION_DEG, DEPRESSION_DEG))
    kvd = gissar.kvd(f["F_calibrated"])
    dpsi = f["heading_change_deg"]
    say(f"F: {len(f['inliers'])}/{len(x1)} inliers, RMS {f['rms_gs_px']:.2f} px; KvD s = {kvd['s']:.4f}, "
        f"theta = {kvd['theta_deg']:.2f} deg, phi = {kvd['phi_deg']:.2f} deg; heading change {dpsi:.3f} deg "
        f"(true {HEADINGS_DEG[1] - HEADINGS_DEG[0]:.1f}, INS {HEADINGS_DEG[1] + INS_HEADING_ERROR_DEG:.1f})")
    save("kvd.png", gissar.kvd_diagram(kvd["s"], kvd["theta_deg"], kvd["phi_deg"], dpsi))
    every = slice(None, None, max(1, len(x1) // 30))  # about 30 matches drawn: readable
    inlier = np.zeros(len(x1), bool)
    inlier[f["inliers"]] = True
    save("matches_epipolar.png",
         gissar.epipolar_plot(sims[0], sims[1], x1[every], x2[every], f["F"],
                              inliers=list(np.flatnonzero(inlier[every]))))
    # Registration: image 2 warped onto image 1 by the affine map of the matches. Flat ground lines up
    # (grey); relief that the plane map cannot follow shows as green/magenta fringes.
    reg = gissar.register_images(sims[0], sims[1], x1, x2, transform="affine")
    save("registration_composite.png", gissar.composite(sims[0], reg["warped"]))
    say(f"registration: affine RMS {reg['rms_px']:.2f} px over {len(reg['inliers'])} inliers (relief parallax)")

    # 5. Pose fix of pass 2 from its image and the scene, starting at the drifted INS pose.
    truth = np.array(g2.sensor_position())
    prior = {"heading_deg": HEADINGS_DEG[1] + INS_HEADING_ERROR_DEG, "slant_range_m": SLANT_RANGE_M,
             "sensor_enu_m": list(truth + INS_POSITION_ERROR_M)}
    with open(os.path.join(out, "prior.json"), "w") as f_prior:  # for `gissar locate --prior`
        json.dump(prior, f_prior)
    fix = gissar.locate(scene, sims[1], prior, range_spacing_m=SPACING_M, azimuth_spacing_m=SPACING_M)
    pose = fix["pose"]
    prior_error = np.linalg.norm(np.array(fix["prior"]["sensor_enu_m"]) - truth)
    fix_error = np.linalg.norm(np.array(pose["sensor_enu_m"]) - truth)
    say(f"pose fix: converged {fix['converged']} in {fix['iterations']} iterations, {fix['inliers']} inliers; "
        f"heading {pose['heading_deg']:.3f} deg (true {HEADINGS_DEG[1]:.1f}), depression "
        f"{pose['depression_deg']:.3f} deg (true {DEPRESSION_DEG:.1f}); sensor position error "
        f"{prior_error:.1f} m -> {fix_error:.1f} m")
    # Real (here: the observed image) vs simulated, at the prior and at the fix.
    # Green: the observed image; magenta: the simulation. Grey where they agree.
    save("locate_composite.png", gissar.side_by_side(
        [gissar.composite(sims[1], fix["reference_at_prior"]),
         gissar.composite(sims[1], fix["reference_at_fix"])],
        [f"INS prior: {prior_error:.0f} m off", f"pose fix: {fix_error:.0f} m off"]))

    # The figures docs/tutorial.md quotes (`make docs-numbers` writes them into it; the docs test
    # compares them): results.json beside the pictures.
    results = {
        "triangles": len(scene.triangles), "matches": len(x1), "f_inliers": len(f["inliers"]),
        "f_rms_px": f["rms_gs_px"], "kvd_s": kvd["s"], "kvd_theta_deg": kvd["theta_deg"],
        "kvd_phi_deg": kvd["phi_deg"], "heading_change_deg": dpsi, "registration_rms_px": reg["rms_px"],
        "registration_inliers": len(reg["inliers"]), "fix_iterations": fix["iterations"],
        "fix_inliers": fix["inliers"], "fix_heading_deg": pose["heading_deg"],
        "fix_depression_deg": pose["depression_deg"], "prior_error_m": prior_error, "fix_error_m": fix_error,
    }
    with open(os.path.join(out, "results.json"), "w") as f_results:
        json.dump({k: float(v) for k, v in results.items()}, f_results, indent=1)

    # Checks: every picture written, the results where they must be.
    missing = [p for p in pictures if not (os.path.isfile(p) and os.path.getsize(p) > 0)]
    failures = []
    if missing:
        failures.append(f"missing pictures: {missing}")
    if abs(dpsi - (HEADINGS_DEG[1] - HEADINGS_DEG[0])) > 0.5:
        failures.append(f"heading change {dpsi:.3f} deg is off by more than 0.5 deg")
    if not fix["converged"] or not fix_error < 0.5 * prior_error:
        failures.append(f"pose fix did not halve the INS error ({prior_error:.1f} m -> {fix_error:.1f} m)")
    say(f"{len(pictures)} pictures in {out}:\n  " + "\n  ".join(os.path.basename(p) for p in pictures))
    for failure in failures:
        print("tutorial: FAILED:", failure, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

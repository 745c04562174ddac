//! `raytracer bench`: medians of parse, build, primary-ray and shadow-ray times on
//! one scene, printed as one JSON object for `bench/run.sh`.

use raytracer::benchmark::{
    RayWorkload, count_occluded, median_time, median_time_with, trace_closest_primitives,
};
use raytracer::{BvhParams, Scene, render};

use super::args::BenchArgs;

/// Measures as `args` say.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let path = &args.view.scene;
    let file_bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let (loaded, parse_s) = median_time(args.repeat, || super::load_scene(&args.view));
    let (description, options) = loaded?;
    let options = &options;
    let triangles = description.triangles.len();
    let params = BvhParams::default();
    // The copy of the description each build consumes is made outside the clock: a
    // render builds from the one it read.
    let (scene, build_s) = median_time_with(
        args.repeat,
        || description.clone(),
        |d| Scene::build(d, &params),
    );
    let workload = RayWorkload::new(&scene, options);
    let (ids, primary_s) = median_time(args.repeat, || {
        trace_closest_primitives(&scene, &workload.primary)
    });
    anyhow::ensure!(
        ids.iter().filter(|&&id| id != u32::MAX).count() == workload.primary_hits,
        "closest-hit runs disagree on the number of hits"
    );
    let (occluded, shadow_s) =
        median_time(args.repeat, || count_occluded(&scene, &workload.shadow));
    let (_, render_s) = median_time(args.repeat, || render(&scene, options));
    let mrays = |n: usize, s: f64| n as f64 / s / 1e6;
    println!(
        concat!(
            "{{\"file_bytes\": {}, \"triangles\": {}, \"parse_ms\": {:.2}, \"parse_mb_per_s\": {:.1}, ",
            "\"build_ms\": {:.2}, \"bvh_nodes\": {}, \"sah_cost\": {:.2}, \"wide_nodes\": {}, \"packets\": {}, ",
            "\"primary_rays\": {}, \"primary_hits\": {}, \"primary_ms\": {:.2}, \"primary_mrays_per_s\": {:.2}, ",
            "\"shadow_rays\": {}, \"shadow_occluded\": {}, \"shadow_ms\": {:.2}, \"shadow_mrays_per_s\": {:.2}, ",
            "\"render_ms\": {:.2}}}"
        ),
        file_bytes,
        triangles,
        parse_s * 1e3,
        file_bytes as f64 / parse_s / 1e6,
        build_s * 1e3,
        scene.bvh_summary().nodes,
        scene.bvh_summary().sah_cost,
        scene.bvh_summary().wide_nodes,
        scene.bvh_summary().packets,
        workload.primary.len(),
        workload.primary_hits,
        primary_s * 1e3,
        mrays(workload.primary.len(), primary_s),
        workload.shadow.len(),
        occluded,
        shadow_s * 1e3,
        mrays(workload.shadow.len(), shadow_s),
        render_s * 1e3,
    );
    Ok(())
}

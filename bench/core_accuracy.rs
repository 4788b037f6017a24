//! Calibration and height accuracy from ground-truth head/foot points:
//! every simulated scene (two seeds) and PETS 2009 S2.L1 boxes.
//! `cargo run --release --example core_accuracy`

use stature::calibrate::eval::{evaluate, pets_people, quantile, sim_people, Accuracy};
use stature::camera::Camera;
use stature::source::sim::scene::scenes;

fn line(name: &str, a: &Accuracy, cam: Option<&Camera>) {
    let Some(e) = a.prior_matched else {
        println!("{name}: no calibration");
        return;
    };
    let k = a.known_height.unwrap();
    let (ae, sf) = (a.abs_errors(), a.scale_free_errors());
    match cam {
        Some(c) => println!(
            "{name:<14} f {:7.1}/{:7.1} ({:+.2}%)  tilt {:6.2}/{:6.2}  roll {:5.2}/{:5.2}  hc {:5.2}/{:5.2} ({:+.2}%)  conf {:.2}  people {:2}  |h| med {:.3} p90 {:.3}  scale-free med {:.4} p90 {:.4}",
            e.geom.focal(), c.f, 100.0 * (e.geom.focal() / c.f - 1.0),
            e.geom.tilt().to_degrees(), c.tilt.to_degrees(),
            e.geom.roll().to_degrees(), c.roll.to_degrees(),
            e.camera_height, c.height, 100.0 * (e.camera_height / c.height - 1.0),
            k.confidence, a.heights.len(),
            quantile(&ae, 0.5), quantile(&ae, 0.9), quantile(&sf, 0.5), quantile(&sf, 0.9)
        ),
        None => println!(
            "{name:<14} f {:7.1} tilt {:6.2} roll {:5.2} hc(prior) {:5.2} vvp ({:.1}, {:.1}) horizon v@centre {:.1} conf {:.2} people {:2} |h| med {:.3} p90 {:.3} scale-free med {:.4} p90 {:.4}",
            e.geom.focal(), e.geom.tilt().to_degrees(), e.geom.roll().to_degrees(), e.camera_height,
            e.geom.v[0], e.geom.v[1],
            { let hz = e.geom.horizon(); -(hz[0] * 383.5 + hz[2]) / hz[1] },
            k.confidence, a.heights.len(),
            quantile(&ae, 0.5), quantile(&ae, 0.9), quantile(&sf, 0.5), quantile(&sf, 0.9)
        ),
    }
}

fn main() {
    for spec in scenes() {
        for seed in [1u64, 7] {
            match sim_people(spec.name, seed, 0.7) {
                Ok((people, cam, w, h)) => {
                    let a = evaluate(&people, cam.height, w, h, stature::track::RING);
                    line(&format!("{}:{seed}", spec.name), &a, Some(&cam));
                }
                Err(e) => println!("{}: {e}", spec.name),
            }
        }
    }
    if let Some(dir) = stature::dataset::shared_data_dir() {
        let g = stature::dataset::load_pets_geometry(&dir).unwrap();
        let people = pets_people(&dir).unwrap();
        let a = evaluate(&people, g.camera_height_m, 768, 576, stature::track::RING);
        line("pets-gt", &a, None);
        println!(
            "pets truth     f {:7.1} tilt {:6.2} roll {:5.2} hc {:5.2} vvp ({:.1}, {:.1}) horizon v@centre {:.1}",
            g.focal_px, g.tilt_deg, g.roll_deg, g.camera_height_m, g.vertical_vp[0], g.vertical_vp[1],
            -(g.horizon[0] * 383.5 + g.horizon[2]) / g.horizon[1]
        );
        for (id, t, e, n) in &a.heights {
            println!(
                "  pets id {id:2}: true {t:.3} est {e:.3} ({:+.3}) from {n} samples",
                e - t
            );
        }
    }
}

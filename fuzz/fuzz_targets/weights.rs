//! Any bytes given to the SVM weight-blob loader load or are refused with a
//! named reason; never a panic. A loaded model re-serialises to a blob that
//! loads to the same model.
#![no_main]
use libfuzzer_sys::fuzz_target;
use stature::classify::svm::Model;

fuzz_target!(|data: &[u8]| {
    if let Ok(model) = Model::from_bytes(data) {
        let again = Model::from_bytes(&model.to_bytes()).expect("a saved model loads");
        assert_eq!(again.to_bytes(), model.to_bytes());
    }
});

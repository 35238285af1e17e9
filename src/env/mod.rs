//! Environments: ReacherDelivery (MuJoCo) and OfficeWorld, with their labelling functions.

//! The MPI job a command runs in (`--mpi`): this process's rank, the number
//! of ranks, and the few collective operations gwml needs: broadcasting a
//! plan from rank 0, gathering results on it, and summing gradients. With
//! one process (no `--mpi`) every operation is the identity, so commands
//! have one code path. MPI comes from the cargo feature `mpi`; a build
//! without it refuses `--mpi` with a message saying how to get it.

/// This process's place in the job.
pub struct World {
    rank: usize,
    size: usize,
    #[cfg(feature = "mpi")]
    mpi: Option<(mpi::environment::Universe, mpi::topology::SimpleCommunicator)>,
}

impl World {
    /// One process, no MPI.
    pub fn single() -> World {
        World {
            rank: 0,
            size: 1,
            #[cfg(feature = "mpi")]
            mpi: None,
        }
    }

    /// The MPI job when `mpi` is set (MPI is initialised here, once per
    /// process), else one process.
    pub fn new(mpi: bool) -> Result<World, String> {
        if !mpi {
            return Ok(World::single());
        }
        World::init()
    }

    #[cfg(feature = "mpi")]
    fn init() -> Result<World, String> {
        use mpi::traits::Communicator;
        let universe = mpi::initialize().ok_or("error: --mpi: MPI was already initialised in this process")?;
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        Ok(World { rank, size, mpi: Some((universe, world)) })
    }

    #[cfg(not(feature = "mpi"))]
    fn init() -> Result<World, String> {
        Err("error: --mpi: this gwml was built without MPI; build it with `cargo build --release --features mpi` \
             (needs a system MPI, e.g. Debian's libopenmpi-dev and openmpi-bin, and libclang-dev)"
            .into())
    }

    /// This process's rank (0 without MPI).
    pub fn rank(&self) -> usize {
        self.rank
    }

    /// Number of processes in the job (1 without MPI).
    pub fn size(&self) -> usize {
        self.size
    }

    /// Rank 0: the one that plans, gathers, prints and writes.
    pub fn is_root(&self) -> bool {
        self.rank == 0
    }

    /// Rank 0's `bytes`, on every rank.
    pub fn broadcast(&self, bytes: Vec<u8>) -> Vec<u8> {
        #[cfg(feature = "mpi")]
        if let Some((_, world)) = &self.mpi {
            use mpi::traits::{Communicator, Root};
            let root = world.process_at_rank(0);
            let mut len = bytes.len() as u64;
            root.broadcast_into(&mut len);
            let mut buf = if self.is_root() { bytes } else { vec![0u8; len as usize] };
            root.broadcast_into(&mut buf[..]);
            return buf;
        }
        bytes
    }

    /// Every rank's `bytes`, in rank order, on rank 0 (`None` elsewhere).
    pub fn gather(&self, bytes: Vec<u8>) -> Option<Vec<Vec<u8>>> {
        #[cfg(feature = "mpi")]
        if let Some((_, world)) = &self.mpi {
            use mpi::datatype::PartitionMut;
            use mpi::traits::{Communicator, Root};
            let root = world.process_at_rank(0);
            let len = bytes.len() as mpi::Count;
            if !self.is_root() {
                root.gather_into(&len);
                root.gather_varcount_into(&bytes[..]);
                return None;
            }
            let mut counts = vec![0 as mpi::Count; self.size];
            root.gather_into_root(&len, &mut counts[..]);
            let displs: Vec<mpi::Count> = counts.iter().scan(0, |at, &c| Some(std::mem::replace(at, *at + c))).collect();
            let mut all = vec![0u8; counts.iter().map(|&c| c as usize).sum()];
            root.gather_varcount_into_root(&bytes[..], &mut PartitionMut::new(&mut all[..], &counts[..], &displs[..]));
            let parts = counts.iter().zip(&displs).map(|(&c, &d)| all[d as usize..(d + c) as usize].to_vec()).collect();
            return Some(parts);
        }
        Some(vec![bytes])
    }

    /// `values` summed elementwise over every rank, on every rank.
    pub fn sum(&self, values: &mut [f64]) {
        #[cfg(feature = "mpi")]
        if let Some((_, world)) = &self.mpi {
            use mpi::collective::SystemOperation;
            use mpi::traits::CommunicatorCollectives;
            let local = values.to_vec();
            world.all_reduce_into(&local[..], values, SystemOperation::sum());
        }
        let _ = values;
    }
}

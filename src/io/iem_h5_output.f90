!> Parallel HDF5 writer of the iem output file: header, mesh, frames, history (docs/output.md).
!>
!> Every rank calls every procedure (they are collective). Node datasets are global and in
!> global node order: each rank writes its owned nodes through a file selection built once in
!> `create`, with collective MPI-IO transfers. Failures are returned in stat/msg, never stopped:
!> stat = 0 success, h5_output_sidecar_error only the .xmf failed, other values: failure.
module iem_h5_output
  use iem_kinds, only: wp, i8
  use mpi_f08, only: MPI_Comm
  use hdf5, only: HID_T, h5close_f
  use iem_h5_layout, only: n_energies, n_static
  implicit none
  private
  public :: h5_output_t, h5_library_close

  !> stat (on every rank) of a call whose HDF5 work succeeded but whose sidecar (.xmf)
  !> could not be written by rank 0; the HDF5 file is fine.
  integer, parameter, public :: h5_output_sidecar_error = 2

  !> Series of /history/fracture/events (time, x, y, kind, cell, spring), and the fragment
  !> sizes in /history/fracture/largest_fragments.
  integer, parameter, public :: n_event_series = 6, n_largest_fragments = 5

  !> Whether this module has opened the HDF5 library (h5open_f) and not closed it yet.
  logical :: library_open = .false.

  !> State of one open output file; all ranks of the communicator hold one.
  type :: h5_output_t
    private
    logical :: is_open = .false.
    logical :: mesh_written = .false.
    !> Whether /mesh/coordinates is written (by write_mesh_coordinates or write_mesh).
    logical :: coords_written = .false.
    !> The caller's communicator (not duplicated); it must outlive the open file.
    type(MPI_Comm) :: comm
    integer :: rank = 0
    integer :: n_ranks = 1
    character(len=:), allocatable :: path, xmf_path, h5_name
    integer(i8) :: n_nodes = 0, n_cells = 0, n_owned = 0, n_frames = 0, n_samples = 0
    !> Contiguous runs of this rank's owned global nodes: first gid (0-based) and length.
    integer(i8), allocatable :: run_start(:), run_len(:)
    !> Times of the frames written so far (rank 0 only, for the sidecar); grows by doubling.
    real(wp), allocatable :: frame_times(:)
    !> Fields each of those frames holds, bits of iem_xdmf's xdmf_field_bit (rank 0 only).
    integer, allocatable :: frame_fields(:)
    !> /mesh fields of iem_xdmf's table found in the file when the sidecar was last written.
    integer :: mesh_fields = 0
    integer(HID_T) :: file_id = -1, frames_id = -1
    integer(HID_T) :: xfer_id = -1, dcpl_id = -1, real_mtype = -1, int_mtype = -1
    !> File space (2, n_nodes) with this rank's nodes selected; memory space (2, n_owned).
    integer(HID_T) :: node_fspace = -1, node_mspace = -1
    integer(HID_T) :: frames_time_id = -1, frames_step_id = -1
    integer(HID_T) :: hist_time_id = -1, hist_step_id = -1
    integer(HID_T) :: energy_id(n_energies) = -1
    !> Whether the file is of a static run (analysis = 'static'), with /history/static.
    logical :: static = .false.
    integer(HID_T) :: static_id(n_static) = -1
    integer(HID_T), allocatable :: probe_u_id(:), probe_v_id(:)
    !> Group path of each probe, /history/probes/<name> (blank padded), for messages.
    character(len=:), allocatable :: probe_path(:)
    !> Spring probes: strain and stress series (12 springs of a cell) and their paths.
    integer(HID_T), allocatable :: spring_e_id(:), spring_s_id(:)
    character(len=:), allocatable :: spring_path(:)
    integer(i8) :: n_spring_samples = 0
    !> /history/reactions/<name>, (2, samples) each, and their paths; samples written of
    !> them and of the fragment series.
    integer(HID_T), allocatable :: reaction_id(:)
    character(len=:), allocatable :: reaction_path(:)
    integer(i8) :: n_series_samples = 0
    !> Whether the file has /history/fracture: its event series, fragments and
    !> largest_fragments, and the events written.
    logical :: fracture = .false.
    integer(HID_T) :: event_id(n_event_series) = -1
    integer(HID_T) :: fragments_id = -1, largest_id = -1
    integer(i8) :: n_events = 0
    !> Contiguous runs of this rank's cells (from write_mesh), for cell fields of frames.
    integer(i8), allocatable :: cell_start(:), cell_len(:)
  contains
    procedure :: create => h5_output_create
    procedure :: write_mesh => h5_output_write_mesh
    procedure :: write_mesh_coordinates => h5_output_write_mesh_coordinates
    procedure :: write_frame => h5_output_write_frame
    procedure :: write_history => h5_output_write_history
    procedure :: write_static_settings => h5_output_write_static_settings
    procedure :: define_spring_probes => h5_output_define_spring_probes
    procedure :: write_spring_history => h5_output_write_spring_history
    procedure :: write_cell_field => h5_output_write_cell_field
    procedure :: write_failed_springs => h5_output_write_failed_springs
    procedure :: define_reactions => h5_output_define_reactions
    procedure :: define_fracture_history => h5_output_define_fracture_history
    procedure :: write_series => h5_output_write_series
    procedure :: write_events => h5_output_write_events
    procedure :: reopen_series => h5_output_reopen_series
    procedure :: reopen => h5_output_reopen
    procedure :: set_owned => h5_output_set_owned
    procedure :: record_continuation => h5_output_record_continuation
    procedure :: samples_written => h5_output_samples_written
    procedure :: frames_written => h5_output_frames_written
    procedure :: close => h5_output_close
  end type h5_output_t

  interface
    ! the type-bound procedures (iem_h5_output_file, _mesh, _frames, _history, _reopen)
    !> Creates the output file collectively (stat /= 0 if it exists and overwrite is off).
    module subroutine h5_output_create(this, path, comm, overwrite, version, input_file, &
        input_text, &
        analysis, n_nodes, n_cells, owned_gids, probe_names, probe_xy, probe_node, probe_node_xy, &
        stat, msg)
      class(h5_output_t), intent(inout) :: this
      character(len=*), intent(in) :: path, version, input_file, input_text, analysis
      type(MPI_Comm), intent(in) :: comm
      logical, intent(in) :: overwrite
      integer(i8), intent(in) :: n_nodes, n_cells
      integer(i8), intent(in) :: owned_gids(:)
      character(len=*), intent(in) :: probe_names(:)
      real(wp), intent(in) :: probe_xy(:, :)
      integer(i8), intent(in) :: probe_node(:)
      real(wp), intent(in) :: probe_node_xy(:, :)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_create

    !> Writes /mesh and its attributes collectively, each rank its owned nodes and its cells
    !> (with material, the cells' material numbers, 1-based, and the materials' names);
    !> coords absent: write_mesh_coordinates has written them.
    module subroutine h5_output_write_mesh(this, coords, mass, cells, cell_gids, nx, ny, lx, ly, &
        thickness, plane, stat, msg, material, material_names)
      class(h5_output_t), intent(inout) :: this
      real(wp), intent(in), optional :: coords(:, :)
      real(wp), intent(in) :: mass(:), lx, ly, thickness
      integer(i8), intent(in) :: cells(:, :), cell_gids(:)
      integer, intent(in) :: nx, ny
      character(len=*), intent(in) :: plane
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
      integer(i8), intent(in), optional :: material(:)
      character(len=*), intent(in), optional :: material_names
    end subroutine h5_output_write_mesh

    !> Writes /mesh/coordinates collectively, each rank its owned nodes (coords(2, n_owned)),
    !> ahead of write_mesh, so that the caller can free coords before it makes the cells.
    module subroutine h5_output_write_mesh_coordinates(this, coords, stat, msg)
      class(h5_output_t), intent(inout) :: this
      real(wp), intent(in) :: coords(:, :)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_write_mesh_coordinates

    !> Adds the next frame group (u, v of the owned nodes) and appends to /frames/time, step.
    !> u and v are rows u_row:u_row+1 and v_row:v_row+1 (default 1) of their arrays (n_owned
    !> columns): a state y(:, 1:n_owned) is passed as it is, and each field goes through one
    !> buffer of at most 32768 nodes, a slab at a time (no copy of a whole field).
    module subroutine h5_output_write_frame(this, step, time, u, v, stat, msg, u_row, v_row)
      class(h5_output_t), intent(inout) :: this
      integer(i8), intent(in) :: step
      real(wp), intent(in) :: time, u(:, :), v(:, :)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
      integer, intent(in), optional :: u_row, v_row
    end subroutine h5_output_write_frame

    !> Appends n samples to /history collectively; every rank passes the same data.
    module subroutine h5_output_write_history(this, n, time, step, energies, probe_u, probe_v, &
        stat, msg, &
        load_factor, iterations, residual)
      class(h5_output_t), intent(inout) :: this
      integer, intent(in) :: n
      real(wp), intent(in) :: time(:), energies(:, :), probe_u(:, :, :), probe_v(:, :, :)
      integer(i8), intent(in) :: step(:)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
      real(wp), intent(in), optional :: load_factor(:), residual(:)
      integer(i8), intent(in), optional :: iterations(:)
    end subroutine h5_output_write_history

    !> Writes the settings of a static run as attributes of /history/static; collective, the
    !> same values on every rank.
    module subroutine h5_output_write_static_settings(this, load_steps, tolerance, max_iterations, &
        method, mass, check_interval, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer, intent(in) :: load_steps, max_iterations, check_interval
      real(wp), intent(in) :: tolerance
      character(len=*), intent(in) :: method, mass
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_write_static_settings

    !> Creates /history/springs/<name>/strain and /stress, (12, samples) each, for spring probes
    !> (the 12 springs of one cell: edges 1-4, Poisson springs 1-4, shear springs 1-4), with the
    !> cell's global index and the probe point as attributes; collective, same arguments on
    !> every rank, after create and before the first write_spring_history.
    module subroutine h5_output_define_spring_probes(this, names, cell_gids, xy, stat, msg)
      class(h5_output_t), intent(inout) :: this
      character(len=*), intent(in) :: names(:)
      integer(i8), intent(in) :: cell_gids(:)
      real(wp), intent(in) :: xy(:, :)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_define_spring_probes

    !> Appends n samples of the spring probes: strain and stress (12, n_spring_probes, n),
    !> the same on every rank (rank 0 writes); collective.
    module subroutine h5_output_write_spring_history(this, n, strain, stress, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer, intent(in) :: n
      real(wp), intent(in) :: strain(:, :, :), stress(:, :, :)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_write_spring_history

    !> Writes a cell field, values(n) for this rank's cells in the order given to write_mesh,
    !> as /frames/<last frame>/<name> (n_cells values); collective, after write_frame. Rank 0
    !> then rewrites the sidecar, which lists the field if iem_xdmf's table has it.
    module subroutine h5_output_write_cell_field(this, name, values, stat, msg)
      class(h5_output_t), intent(inout) :: this
      character(len=*), intent(in) :: name
      real(wp), intent(in) :: values(:)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_write_cell_field

    !> Writes the group /frames/<last frame>/failed_springs: datasets cell (int64), spring,
    !> kind (int32, from kinds) and time (float64) of one length, the entries of every rank
    !> (each passes its own equal-sized arrays, in any order) sorted by (cell, spring), so the
    !> same bytes on any number of ranks; empty lists make zero-length datasets. Collective,
    !> after write_frame; rank 0 gathers and writes the entries.
    module subroutine h5_output_write_failed_springs(this, cell, spring, kinds, time, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer(i8), intent(in) :: cell(:)
      integer, intent(in) :: spring(:), kinds(:)
      real(wp), intent(in) :: time(:)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_write_failed_springs

    !> Reopens the output of an interrupted dynamic run to append to it: keeps its first
    !> n_samples history samples and n_frames frames (later ones, written after the checkpoint
    !> the run continues from, are removed, so the history has no gap and no duplicate), marks
    !> it incomplete, and prepares this rank's node and cell selections as create and
    !> write_mesh do. Collective; the arguments as for create (probe and spring probe names
    !> must match the file).
    !> After a repartition: this rank now writes the nodes owned_gids and the counted cells
    !> cell_gids (both ascending) of every later frame. Collective.
    module subroutine h5_output_set_owned(this, owned_gids, cell_gids, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer(i8), intent(in) :: owned_gids(:), cell_gids(:)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_set_owned

    module subroutine h5_output_reopen(this, path, comm, n_nodes, n_cells, owned_gids, cell_gids, &
        probe_names, spring_names, n_samples, n_frames, stat, msg)
      class(h5_output_t), intent(inout) :: this
      character(len=*), intent(in) :: path
      type(MPI_Comm), intent(in) :: comm
      integer(i8), intent(in) :: n_nodes, n_cells, n_samples, n_frames
      integer(i8), intent(in) :: owned_gids(:), cell_gids(:)
      character(len=*), intent(in) :: probe_names(:), spring_names(:)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_reopen

    !> Adds /continuations/NNNN (1, 2, ...: one per continuation) with the attributes checkpoint
    !> (its path as given), time and step (where the run continued), n_ranks, date (the wall
    !> clock at the continuation, ISO 8601, of rank 0), samples and frames (what the file kept
    !> of the run before). Collective.
    module subroutine h5_output_record_continuation(this, checkpoint, time, step, stat, msg)
      class(h5_output_t), intent(inout) :: this
      character(len=*), intent(in) :: checkpoint
      real(wp), intent(in) :: time
      integer(i8), intent(in) :: step
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_record_continuation

    !> Closes the file collectively, after setting complete = 1 as the last write if `complete`.
    module subroutine h5_output_close(this, complete, stat, msg)
      class(h5_output_t), intent(inout) :: this
      logical, intent(in) :: complete
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_close

    ! /history/reactions and /history/fracture (iem_h5_output_series)
    !> Creates /history/reactions/<name>, (2, samples) float64 each (the force of the
    !> prescribed dofs of one or more &bc, x and y), with the attribute bcs (those &bc, 1-based,
    !> as text); collective, the same arguments on every rank, after create.
    module subroutine h5_output_define_reactions(this, names, bcs, stat, msg)
      class(h5_output_t), intent(inout) :: this
      character(len=*), intent(in) :: names(:), bcs(:)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_define_reactions

    !> Creates /history/fracture: events/time, x, y (float64), kind (int32), cell (int64),
    !> spring (int32), one entry a failure, and fragments (samples) and largest_fragments
    !> (n_largest_fragments, samples) int64; collective, after create.
    module subroutine h5_output_define_fracture_history(this, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_define_fracture_history

    !> Appends n samples of the reactions (2, n_series, n) and, in a file with
    !> /history/fracture (and only then), of fragments(n) and largest(n_largest_fragments, n);
    !> the same on every rank (rank 0 writes); collective.
    module subroutine h5_output_write_series(this, n, reactions, stat, msg, fragments, largest)
      class(h5_output_t), intent(inout) :: this
      integer, intent(in) :: n
      real(wp), intent(in) :: reactions(:, :, :)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
      integer(i8), intent(in), optional :: fragments(:), largest(:, :)
    end subroutine h5_output_write_series

    !> Appends n fracture events to /history/fracture/events (n the same on every rank; the
    !> events are read on rank 0 only, the other ranks' arrays may be empty but allocated);
    !> collective. Nothing in a file without /history/fracture.
    module subroutine h5_output_write_events(this, n, time, x, y, kind, cell, spring, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer, intent(in) :: n
      real(wp), intent(in) :: time(:), x(:), y(:)
      integer, intent(in) :: kind(:), spring(:)
      integer(i8), intent(in) :: cell(:)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_write_events

    !> After reopen: opens /history/reactions/<names> and, with fracture, /history/fracture,
    !> cut to the n_samples samples kept and to the events up to time t_last (that of the
    !> last sample kept); collective.
    module subroutine h5_output_reopen_series(this, names, fracture, n_samples, t_last, stat, &
        msg)
      class(h5_output_t), intent(inout) :: this
      character(len=*), intent(in) :: names(:)
      logical, intent(in) :: fracture
      integer(i8), intent(in) :: n_samples
      real(wp), intent(in) :: t_last
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine h5_output_reopen_series

    ! used by more than one submodule
    !> Opens the HDF5 library if needed, sets the memory types, and makes the file access list
    !> for parallel I/O on comm with collective metadata (the caller closes fapl).
    module subroutine file_access_list(this, comm, fapl, stat, msg)
      class(h5_output_t), intent(inout) :: this
      type(MPI_Comm), intent(in) :: comm
      integer(HID_T), intent(inout) :: fapl
      integer, intent(inout) :: stat
      character(len=:), allocatable, intent(inout) :: msg
    end subroutine file_access_list

    !> The collective transfer list and the dataset creation list (no fill values: every
    !> element of every dataset is written) of an open file.
    module subroutine dataset_lists(this, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer, intent(inout) :: stat
      character(len=:), allocatable, intent(inout) :: msg
    end subroutine dataset_lists

    !> (Re)build the selection of this rank's nodes that every frame uses, from run_start,
    !> run_len and n_owned: the file space (2, n_nodes) and the memory space (2, n_owned).
    module subroutine select_owned_nodes(this, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer, intent(inout) :: stat
      character(len=:), allocatable, intent(inout) :: msg
    end subroutine select_owned_nodes

    !> Rank 0 rewrites the sidecar with the frames written so far and the /mesh fields the
    !> open file holds; collective, so that every rank learns of a failure (then
    !> stat = h5_output_sidecar_error unless already set).
    module subroutine write_sidecar(this, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer, intent(inout) :: stat
      character(len=:), allocatable, intent(inout) :: msg
    end subroutine write_sidecar

    !> Closes every open object and the file, after a failure; keeps the first error.
    module subroutine release(this, stat, msg)
      class(h5_output_t), intent(inout) :: this
      integer, intent(inout) :: stat
      character(len=:), allocatable, intent(inout) :: msg
    end subroutine release
  end interface

contains

  !> History samples written so far.
  pure integer(i8) function h5_output_samples_written(this) result(n)
    class(h5_output_t), intent(in) :: this
    n = this%n_samples
  end function h5_output_samples_written

  !> Frames written so far.
  pure integer(i8) function h5_output_frames_written(this) result(n)
    class(h5_output_t), intent(in) :: this
    n = this%n_frames
  end function h5_output_frames_written

  !> Closes the HDF5 library at program end, after every output file has been closed.
  subroutine h5_library_close(stat)
    integer, intent(out), optional :: stat
    integer :: ierr

    ierr = 0
    if (library_open) then
      call h5close_f(ierr)
      if (ierr == 0) library_open = .false.
    end if
    if (present(stat)) stat = ierr
  end subroutine h5_library_close

end module iem_h5_output

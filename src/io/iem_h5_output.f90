!> Parallel HDF5 writer of the iem output file: header, mesh, frames, history (docs/output.md).
!>
!> Every rank calls every procedure (they are collective). Node datasets are global and in
!> global node order: each rank writes its owned nodes through a file selection built once in
!> `create`, with collective MPI-IO transfers. Failures are returned in stat/msg, never stopped:
!> stat = 0 success, h5_output_sidecar_error only the .xmf failed, other values: failure.
module iem_h5_output
  use iem_kinds, only: wp, i8, mpi_i8
  use iem_strings, only: itoa
  use iem_xdmf, only: xdmf_write, xdmf_frame_name, xdmf_path_of
  use iem_paths, only: mpiio_name
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, MPI_Bcast, &
    MPI_INTEGER, MPI_LOGICAL, MPI_MAX, MPI_SUM, MPI_INFO_NULL, MPI_CHARACTER
  use hdf5, only: HID_T, HSIZE_T, SIZE_T, h5open_f, h5close_f, h5kind_to_type, &
    H5_REAL_KIND, H5_INTEGER_KIND, &
    h5pcreate_f, h5pclose_f, h5pset_fapl_mpio_f, h5pset_libver_bounds_f, &
    h5pset_all_coll_metadata_ops_f, h5pset_coll_metadata_write_f, h5pset_dxpl_mpio_f, &
    h5pset_fill_time_f, h5pset_chunk_f, &
    H5P_FILE_ACCESS_F, H5P_DATASET_CREATE_F, H5P_DATASET_XFER_F, H5FD_MPIO_COLLECTIVE_F, &
    H5D_FILL_TIME_NEVER_F, H5F_LIBVER_V18_F, H5F_LIBVER_LATEST_F, &
    h5fcreate_f, h5fclose_f, h5fflush_f, H5F_ACC_TRUNC_F, H5F_ACC_EXCL_F, H5F_SCOPE_GLOBAL_F, &
    h5fopen_f, H5F_ACC_RDWR_F, h5lexists_f, h5ldelete_f, h5dopen_f, h5dread_f, &
    h5sget_simple_extent_dims_f, &
    h5gcreate_f, h5gopen_f, h5gclose_f, h5gget_info_f, &
    h5dcreate_f, h5dwrite_f, h5dclose_f, h5dset_extent_f, h5dget_space_f, &
    h5screate_f, h5screate_simple_f, h5scopy_f, h5sclose_f, h5sselect_hyperslab_f, &
    h5sselect_none_f, H5S_SCALAR_F, H5S_SELECT_SET_F, H5S_SELECT_OR_F, H5S_UNLIMITED_F, &
    h5acreate_f, h5aopen_f, h5awrite_f, h5aclose_f, &
    h5tcopy_f, h5tset_size_f, h5tset_strpad_f, h5tclose_f, H5T_FORTRAN_S1, H5T_STR_NULLPAD_F, &
    H5T_NATIVE_INTEGER, H5T_STD_I32LE, H5T_STD_I64LE, H5T_IEEE_F64LE
  use, intrinsic :: iso_c_binding, only: c_int, c_int64_t
  implicit none
  private
  public :: h5_output_t, h5_library_close

  !> stat (on every rank) of a call whose HDF5 work succeeded but whose sidecar (.xmf)
  !> could not be written by rank 0; the HDF5 file is fine.
  integer, parameter, public :: h5_output_sidecar_error = 2

  interface
    !> C H5Smodify_select (HDF5 >= 1.10.7; no Fortran wrapper in 1.10): merges the selection
    !> of space2 into that of space1 with operator op. Negative on failure. hid_t is int64_t.
    function h5s_modify_select(space1, op, space2) bind(C, name='H5Smodify_select') &
        result(herr)
      import :: c_int, c_int64_t
      integer(c_int64_t), value :: space1, space2
      integer(c_int), value :: op
      integer(c_int) :: herr
    end function h5s_modify_select
  end interface

  integer, parameter :: n_energies = 5
  character(len=*), parameter :: energy_names(n_energies) = [character(len=13) :: &
    'kinetic', 'strain', 'external_work', 'damping', 'balance_error']
  !> Per-sample series of a static run, in /history/static (docs/output.md).
  integer, parameter :: n_static = 3
  character(len=*), parameter :: static_names(n_static) = [character(len=11) :: &
    'load_factor', 'iterations', 'residual']
  !> Samples per chunk of the extendible datasets (history, /frames/time, /frames/step).
  integer(HSIZE_T), parameter :: series_chunk = 1024
  integer(HSIZE_T), parameter :: one(1) = [1_HSIZE_T]

  !> Whether this module has opened the HDF5 library (h5open_f) and not closed it yet.
  logical :: library_open = .false.

  !> State of one open output file; all ranks of the communicator hold one.
  type :: h5_output_t
    private
    logical :: is_open = .false.
    logical :: mesh_written = .false.
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
    !> Contiguous runs of this rank's cells (from write_mesh), for cell fields of frames.
    integer(i8), allocatable :: cell_start(:), cell_len(:)
  contains
    procedure :: create => h5_output_create
    procedure :: write_mesh => h5_output_write_mesh
    procedure :: write_frame => h5_output_write_frame
    procedure :: write_history => h5_output_write_history
    procedure :: write_static_settings => h5_output_write_static_settings
    procedure :: define_spring_probes => h5_output_define_spring_probes
    procedure :: write_spring_history => h5_output_write_spring_history
    procedure :: write_cell_field => h5_output_write_cell_field
    procedure :: reopen => h5_output_reopen
    procedure :: record_continuation => h5_output_record_continuation
    procedure :: samples_written => h5_output_samples_written
    procedure :: frames_written => h5_output_frames_written
    procedure :: close => h5_output_close
  end type h5_output_t

contains

  !> Creates the output file collectively (stat /= 0 if it exists and overwrite is off).
  subroutine h5_output_create(this, path, comm, overwrite, version, input_file, input_text, &
      analysis, n_nodes, n_cells, owned_gids, probe_names, probe_xy, probe_node, probe_node_xy, &
      stat, msg)
    ! Writes the header attributes, creates the groups and the empty history datasets (with
    ! /history/static when analysis is 'static'), and builds this rank's node selection.
    ! owned_gids: this rank's nodes, 0-based, strictly ascending, a partition of
    ! 0..n_nodes-1 over the ranks. The strings and probe arguments
    ! must be the same on every rank. comm is kept (not duplicated) while the file is open.
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
    character(len=:), allocatable :: local_msg, pname, tmp_msg
    integer(HID_T) :: fapl, hist_id, energy_gid, probes_gid, pgid, static_gid
    integer :: ierr, bad, any_bad, p, k, tmp_stat
    integer(i8) :: total
    logical :: exists

    stat = 0
    msg = ''
    if (this%is_open) then
      call this%close(.false., stat, msg)
      if (stat /= 0) return
    end if
    this%comm = comm
    call MPI_Comm_rank(comm, this%rank)
    call MPI_Comm_size(comm, this%n_ranks)
    this%path = path
    this%xmf_path = xdmf_path_of(path)
    this%h5_name = path(index(path, '/', back=.true.) + 1:)
    this%mesh_written = .false.
    this%n_nodes = n_nodes
    this%n_cells = n_cells
    this%n_owned = size(owned_gids, kind=i8)
    this%n_frames = 0
    this%n_samples = 0
    this%static = analysis == 'static'

    ! Argument checks, agreed by all ranks before the first collective HDF5 call.
    local_msg = check_create_args(n_nodes, n_cells, owned_gids, probe_names, probe_xy, &
      probe_node, probe_node_xy)
    bad = merge(1, 0, len(local_msg) > 0)
    call MPI_Allreduce(bad, any_bad, 1, MPI_INTEGER, MPI_MAX, comm)
    call MPI_Allreduce(this%n_owned, total, 1, mpi_i8(), MPI_SUM, comm)
    if (any_bad /= 0) then
      stat = 1
      if (bad == 0) local_msg = 'invalid arguments on another rank'
      msg = 'iem_h5_output: '//local_msg//' (creating '//path//')'
      return
    end if
    if (total /= n_nodes) then
      stat = 1
      msg = 'iem_h5_output: owned_gids of all ranks hold '//itoa(total)// &
        ' nodes, not n_nodes = '//itoa(n_nodes)//' (creating '//path//')'
      return
    end if

    if (this%rank == 0) inquire (file=path, exist=exists)
    call MPI_Bcast(exists, 1, MPI_LOGICAL, 0, comm)
    if (exists .and. .not. overwrite) then
      stat = 1
      msg = 'iem_h5_output: '//path//' exists and overwrite is off; the file is left untouched'
      return
    end if

    call gid_runs(owned_gids, this%run_start, this%run_len)
    if (allocated(this%probe_u_id)) deallocate (this%probe_u_id, this%probe_v_id)
    allocate (this%probe_u_id(size(probe_names)), this%probe_v_id(size(probe_names)))
    this%probe_u_id = -1
    this%probe_v_id = -1
    if (allocated(this%probe_path)) deallocate (this%probe_path)
    allocate (character(len=len('/history/probes/') + len(probe_names)) :: &
      this%probe_path(size(probe_names)))
    do p = 1, size(probe_names)
      this%probe_path(p) = '/history/probes/'//trim(probe_names(p))
    end do
    if (allocated(this%frame_times)) deallocate (this%frame_times)
    allocate (this%frame_times(16))

    fapl = -1
    hist_id = -1
    energy_gid = -1
    probes_gid = -1
    pgid = -1
    static_gid = -1
    work: block
      call file_access_list(this, comm, fapl, stat, msg)
      if (stat /= 0) exit work
      ! EXCL guards against a file that appeared since the check above.
      call h5fcreate_f(mpiio_name(path), merge(H5F_ACC_TRUNC_F, H5F_ACC_EXCL_F, overwrite), &
                       this%file_id, ierr, access_prp=fapl)
      if (failed(this, ierr, 'h5fcreate_f', '/', stat, msg)) exit work
      this%is_open = .true.
      call dataset_lists(this, stat, msg)
      if (stat /= 0) exit work

      call put_attr(this, this%file_id, '/', 'program', stat, msg, text='iem')
      call put_attr(this, this%file_id, '/', 'file_type', stat, msg, text='iem_output')
      call put_attr(this, this%file_id, '/', 'version', stat, msg, text=version)
      call put_attr(this, this%file_id, '/', 'n_ranks', stat, msg, ival=this%n_ranks)
      call put_attr(this, this%file_id, '/', 'input_file', stat, msg, text=input_file)
      call put_attr(this, this%file_id, '/', 'input_text', stat, msg, text=input_text)
      call put_attr(this, this%file_id, '/', 'analysis', stat, msg, text=analysis)
      call put_attr(this, this%file_id, '/', 'units', stat, msg, text='SI: m, kg, s, N, Pa, J')
      call put_attr(this, this%file_id, '/', 'complete', stat, msg, ival=0)
      if (stat /= 0) exit work

      call h5gcreate_f(this%file_id, 'mesh', pgid, ierr)
      if (failed(this, ierr, 'h5gcreate_f', '/mesh', stat, msg)) exit work
      call h5gclose_f(pgid, ierr)
      pgid = -1
      if (failed(this, ierr, 'h5gclose_f', '/mesh', stat, msg)) exit work

      call h5gcreate_f(this%file_id, 'frames', this%frames_id, ierr)
      if (failed(this, ierr, 'h5gcreate_f', '/frames', stat, msg)) exit work
      call create_series(this, this%frames_id, '/frames/', 'time', H5T_IEEE_F64LE, 0, &
        this%frames_time_id, stat, msg)
      call create_series(this, this%frames_id, '/frames/', 'step', H5T_STD_I64LE, 0, &
        this%frames_step_id, stat, msg)
      if (stat /= 0) exit work

      call h5gcreate_f(this%file_id, 'history', hist_id, ierr)
      if (failed(this, ierr, 'h5gcreate_f', '/history', stat, msg)) exit work
      call create_series(this, hist_id, '/history/', 'time', H5T_IEEE_F64LE, 0, &
        this%hist_time_id, stat, msg)
      call create_series(this, hist_id, '/history/', 'step', H5T_STD_I64LE, 0, &
        this%hist_step_id, stat, msg)
      if (stat /= 0) exit work
      call h5gcreate_f(hist_id, 'energy', energy_gid, ierr)
      if (failed(this, ierr, 'h5gcreate_f', '/history/energy', stat, msg)) exit work
      do k = 1, n_energies
        call create_series(this, energy_gid, '/history/energy/', trim(energy_names(k)), &
          H5T_IEEE_F64LE, 0, this%energy_id(k), stat, msg)
      end do
      if (stat /= 0) exit work
      if (this%static) then
        call h5gcreate_f(hist_id, 'static', static_gid, ierr)
        if (failed(this, ierr, 'h5gcreate_f', '/history/static', stat, msg)) exit work
        call create_series(this, static_gid, '/history/static/', trim(static_names(1)), &
          H5T_IEEE_F64LE, 0, this%static_id(1), stat, msg)
        call create_series(this, static_gid, '/history/static/', trim(static_names(2)), &
          H5T_STD_I64LE, 0, this%static_id(2), stat, msg)
        call create_series(this, static_gid, '/history/static/', trim(static_names(3)), &
          H5T_IEEE_F64LE, 0, this%static_id(3), stat, msg)
        if (stat /= 0) exit work
      end if
      call h5gcreate_f(hist_id, 'probes', probes_gid, ierr)
      if (failed(this, ierr, 'h5gcreate_f', '/history/probes', stat, msg)) exit work
      do p = 1, size(probe_names)
        pname = trim(probe_names(p))
        call h5gcreate_f(probes_gid, pname, pgid, ierr)
        if (failed(this, ierr, 'h5gcreate_f', '/history/probes/'//pname, stat, msg)) exit work
        call put_attr(this, pgid, '/history/probes/'//pname, 'x', stat, msg, rval=probe_xy(1, p))
        call put_attr(this, pgid, '/history/probes/'//pname, 'y', stat, msg, rval=probe_xy(2, p))
        call put_attr(this, pgid, '/history/probes/'//pname, 'node', stat, msg, &
          lval=probe_node(p))
        call put_attr(this, pgid, '/history/probes/'//pname, 'node_x', stat, msg, &
          rval=probe_node_xy(1, p))
        call put_attr(this, pgid, '/history/probes/'//pname, 'node_y', stat, msg, &
          rval=probe_node_xy(2, p))
        call create_series(this, pgid, '/history/probes/'//pname//'/', 'displacement', &
          H5T_IEEE_F64LE, 2, this%probe_u_id(p), stat, msg)
        call create_series(this, pgid, '/history/probes/'//pname//'/', 'velocity', &
          H5T_IEEE_F64LE, 2, this%probe_v_id(p), stat, msg)
        if (stat /= 0) exit work
        call h5gclose_f(pgid, ierr)
        pgid = -1
        if (failed(this, ierr, 'h5gclose_f', '/history/probes/'//pname, stat, msg)) exit work
      end do

      ! The selection of this rank's nodes, built once and used by every frame.
      call h5screate_simple_f(2, [2_HSIZE_T, int(n_nodes, HSIZE_T)], this%node_fspace, ierr)
      if (failed(this, ierr, 'h5screate_simple_f', 'node file space', stat, msg)) exit work
      call select_runs(this, this%node_fspace, 'node file space', 2, this%run_start, &
        this%run_len, stat, msg)
      call make_mem_space(this, 2, this%n_owned, 'node memory space', this%node_mspace, &
        stat, msg)
    end block work

    ! Temporaries, closed on success and on failure alike; the first error is kept.
    tmp_stat = 0
    tmp_msg = ''
    if (pgid >= 0) call h5gclose_f(pgid, ierr)
    if (static_gid >= 0) then
      call h5gclose_f(static_gid, ierr)
      if (failed(this, ierr, 'h5gclose_f', '/history/static', tmp_stat, tmp_msg)) continue
    end if
    if (probes_gid >= 0) then
      call h5gclose_f(probes_gid, ierr)
      if (failed(this, ierr, 'h5gclose_f', '/history/probes', tmp_stat, tmp_msg)) continue
    end if
    if (energy_gid >= 0) then
      call h5gclose_f(energy_gid, ierr)
      if (failed(this, ierr, 'h5gclose_f', '/history/energy', tmp_stat, tmp_msg)) continue
    end if
    if (hist_id >= 0) then
      call h5gclose_f(hist_id, ierr)
      if (failed(this, ierr, 'h5gclose_f', '/history', tmp_stat, tmp_msg)) continue
    end if
    if (fapl >= 0) then
      call h5pclose_f(fapl, ierr)
      if (failed(this, ierr, 'h5pclose_f', 'file access list', tmp_stat, tmp_msg)) continue
    end if
    if (stat == 0 .and. tmp_stat /= 0) then
      stat = tmp_stat
      msg = tmp_msg
    end if

    if (stat /= 0) then
      call release(this, tmp_stat, tmp_msg)
      return
    end if
    call write_sidecar(this, stat, msg)
  end subroutine h5_output_create

  !> Writes /mesh and its attributes collectively, each rank its owned nodes and its cells.
  subroutine h5_output_write_mesh(this, coords, mass, cells, cell_gids, nx, ny, lx, ly, &
      thickness, plane, stat, msg)
    ! coords(2, n_owned), mass(n_owned) in owned_gids order; cells(4, n): 0-based global corner
    ! ids of the cells at the 0-based global, strictly ascending indices cell_gids(n); every
    ! cell is written by exactly one rank.
    class(h5_output_t), intent(inout) :: this
    real(wp), intent(in) :: coords(:, :), mass(:), lx, ly, thickness
    integer(i8), intent(in) :: cells(:, :), cell_gids(:)
    integer, intent(in) :: nx, ny
    character(len=*), intent(in) :: plane
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: local_msg, tmp_msg
    integer(i8), allocatable :: cstart(:), clen(:)
    integer(HID_T) :: gid, did, cell_fspace, cell_mspace, mass_fspace, mass_mspace
    integer(i8) :: n_my_cells, total
    integer :: ierr, bad, any_bad, tmp_stat

    stat = 0
    msg = ''
    if (.not. this%is_open) then
      stat = 1
      msg = 'iem_h5_output: write_mesh on a file that is not open'
      return
    end if
    if (this%mesh_written) then
      stat = 1
      msg = 'iem_h5_output: write_mesh called twice for '//this%path
      return
    end if
    n_my_cells = size(cell_gids, kind=i8)
    local_msg = check_mesh_args(this, coords, mass, cells, cell_gids)
    bad = merge(1, 0, len(local_msg) > 0)
    call MPI_Allreduce(bad, any_bad, 1, MPI_INTEGER, MPI_MAX, this%comm)
    call MPI_Allreduce(n_my_cells, total, 1, mpi_i8(), MPI_SUM, this%comm)
    if (any_bad /= 0) then
      stat = 1
      if (bad == 0) local_msg = 'invalid arguments on another rank'
      msg = 'iem_h5_output: write_mesh: '//local_msg//' ('//this%path//')'
      return
    end if
    if (total /= this%n_cells) then
      stat = 1
      msg = 'iem_h5_output: write_mesh: the ranks hold '//itoa(total)// &
        ' cells, not n_cells = '//itoa(this%n_cells)//' ('//this%path//')'
      return
    end if

    call gid_runs(cell_gids, cstart, clen)
    this%cell_start = cstart
    this%cell_len = clen
    gid = -1
    did = -1
    cell_fspace = -1
    cell_mspace = -1
    mass_fspace = -1
    mass_mspace = -1
    work: block
      call h5gopen_f(this%file_id, 'mesh', gid, ierr)
      if (failed(this, ierr, 'h5gopen_f', '/mesh', stat, msg)) exit work

      call h5dcreate_f(gid, 'coordinates', H5T_IEEE_F64LE, this%node_fspace, did, ierr, &
        this%dcpl_id)
      if (failed(this, ierr, 'h5dcreate_f', '/mesh/coordinates', stat, msg)) exit work
      call h5dwrite_f(did, this%real_mtype, coords, shape(coords, HSIZE_T), ierr, &
        this%node_mspace, this%node_fspace, this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', '/mesh/coordinates', stat, msg)) exit work
      call h5dclose_f(did, ierr)
      did = -1
      if (failed(this, ierr, 'h5dclose_f', '/mesh/coordinates', stat, msg)) exit work

      call h5screate_simple_f(2, [4_HSIZE_T, int(this%n_cells, HSIZE_T)], cell_fspace, ierr)
      if (failed(this, ierr, 'h5screate_simple_f', '/mesh/cells', stat, msg)) exit work
      call select_runs(this, cell_fspace, '/mesh/cells', 4, cstart, clen, stat, msg)
      call make_mem_space(this, 4, n_my_cells, '/mesh/cells', cell_mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dcreate_f(gid, 'cells', H5T_STD_I64LE, cell_fspace, did, ierr, this%dcpl_id)
      if (failed(this, ierr, 'h5dcreate_f', '/mesh/cells', stat, msg)) exit work
      call h5dwrite_f(did, this%int_mtype, cells, shape(cells, HSIZE_T), ierr, cell_mspace, &
        cell_fspace, this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', '/mesh/cells', stat, msg)) exit work
      call h5dclose_f(did, ierr)
      did = -1
      if (failed(this, ierr, 'h5dclose_f', '/mesh/cells', stat, msg)) exit work

      call h5screate_simple_f(1, [int(this%n_nodes, HSIZE_T)], mass_fspace, ierr)
      if (failed(this, ierr, 'h5screate_simple_f', '/mesh/mass', stat, msg)) exit work
      call select_runs(this, mass_fspace, '/mesh/mass', 0, this%run_start, this%run_len, &
        stat, msg)
      call make_mem_space(this, 0, this%n_owned, '/mesh/mass', mass_mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dcreate_f(gid, 'mass', H5T_IEEE_F64LE, mass_fspace, did, ierr, this%dcpl_id)
      if (failed(this, ierr, 'h5dcreate_f', '/mesh/mass', stat, msg)) exit work
      call h5dwrite_f(did, this%real_mtype, mass, shape(mass, HSIZE_T), ierr, mass_mspace, &
        mass_fspace, this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', '/mesh/mass', stat, msg)) exit work
      call h5dclose_f(did, ierr)
      did = -1
      if (failed(this, ierr, 'h5dclose_f', '/mesh/mass', stat, msg)) exit work

      call put_attr(this, gid, '/mesh', 'nx', stat, msg, ival=nx)
      call put_attr(this, gid, '/mesh', 'ny', stat, msg, ival=ny)
      call put_attr(this, gid, '/mesh', 'lx', stat, msg, rval=lx)
      call put_attr(this, gid, '/mesh', 'ly', stat, msg, rval=ly)
      call put_attr(this, gid, '/mesh', 'thickness', stat, msg, rval=thickness)
      call put_attr(this, gid, '/mesh', 'plane', stat, msg, text=plane)
      if (stat /= 0) exit work
      call h5gclose_f(gid, ierr)
      gid = -1
      if (failed(this, ierr, 'h5gclose_f', '/mesh', stat, msg)) exit work
      call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
      if (failed(this, ierr, 'h5fflush_f', '/', stat, msg)) exit work
      this%mesh_written = .true.
    end block work

    tmp_stat = 0
    tmp_msg = ''
    if (did >= 0) call h5dclose_f(did, ierr)
    if (gid >= 0) call h5gclose_f(gid, ierr)
    call close_space(this, cell_fspace, tmp_stat, tmp_msg)
    call close_space(this, cell_mspace, tmp_stat, tmp_msg)
    call close_space(this, mass_fspace, tmp_stat, tmp_msg)
    call close_space(this, mass_mspace, tmp_stat, tmp_msg)
    if (stat == 0 .and. tmp_stat /= 0) then
      stat = tmp_stat
      msg = tmp_msg
    end if
    call write_sidecar(this, stat, msg)
  end subroutine h5_output_write_mesh

  !> Adds the next frame group (u, v of the owned nodes) and appends to /frames/time, step.
  subroutine h5_output_write_frame(this, step, time, u, v, stat, msg)
    ! u, v: (2, n_owned) in owned_gids order. Collective; rank 0 then rewrites the sidecar.
    class(h5_output_t), intent(inout) :: this
    integer(i8), intent(in) :: step
    real(wp), intent(in) :: time, u(:, :), v(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: name, where
    real(wp), allocatable :: grown(:)
    integer(HID_T) :: gid, fspace, mspace
    integer :: ierr
    logical :: shapes_ok

    stat = 0
    msg = ''
    if (.not. this%is_open) then
      stat = 1
      msg = 'iem_h5_output: write_frame on a file that is not open'
      return
    end if
    ! A rank with wrong shapes writes nothing but still takes part in every collective call,
    ! so that the other ranks do not hang; it reports the error afterwards.
    shapes_ok = size(u, 1) == 2 .and. size(u, 2, kind=i8) == this%n_owned .and. &
      size(v, 1) == 2 .and. size(v, 2, kind=i8) == this%n_owned
    name = xdmf_frame_name(this%n_frames)
    where = '/frames/'//name
    gid = -1
    fspace = -1
    mspace = -1
    work: block
      call h5gcreate_f(this%frames_id, name, gid, ierr)
      if (failed(this, ierr, 'h5gcreate_f', where, stat, msg)) exit work
      call put_attr(this, gid, where, 'time', stat, msg, rval=time)
      call put_attr(this, gid, where, 'step', stat, msg, lval=step)
      call write_node_field(this, gid, where//'/displacement', 'displacement', u, shapes_ok, &
        stat, msg)
      call write_node_field(this, gid, where//'/velocity', 'velocity', v, shapes_ok, stat, msg)
      if (stat /= 0) exit work

      call prepare_append(this, this%frames_time_id, '/frames/time', 0, this%n_frames, 1_i8, &
        fspace, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dwrite_f(this%frames_time_id, this%real_mtype, [time], one, ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', '/frames/time', stat, msg)) exit work
      call close_space(this, fspace, stat, msg)
      call close_space(this, mspace, stat, msg)
      call prepare_append(this, this%frames_step_id, '/frames/step', 0, this%n_frames, 1_i8, &
        fspace, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dwrite_f(this%frames_step_id, this%int_mtype, [step], one, ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', '/frames/step', stat, msg)) exit work

      call h5gclose_f(gid, ierr)
      gid = -1
      if (failed(this, ierr, 'h5gclose_f', where, stat, msg)) exit work
      ! Keeps the file readable if the run is killed later.
      call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
      if (failed(this, ierr, 'h5fflush_f', '/', stat, msg)) exit work
    end block work
    if (gid >= 0) call h5gclose_f(gid, ierr)
    call close_space(this, fspace, stat, msg)
    call close_space(this, mspace, stat, msg)

    if (stat == 0) then
      this%n_frames = this%n_frames + 1
      if (this%rank == 0) then
        if (this%n_frames > size(this%frame_times, kind=i8)) then
          allocate (grown(2*size(this%frame_times)))
          grown(:size(this%frame_times)) = this%frame_times
          call move_alloc(grown, this%frame_times)
        end if
        this%frame_times(this%n_frames) = time
      end if
    end if
    call write_sidecar(this, stat, msg)
    if (.not. shapes_ok .and. stat /= 1) then
      stat = 1
      msg = 'iem_h5_output: write_frame: u and v must be (2, '//itoa(this%n_owned)// &
        '), the owned nodes of this rank; nothing written from it to '//where//' in '//this%path
    end if
  end subroutine h5_output_write_frame

  !> Appends n samples to /history collectively; every rank passes the same data.
  subroutine h5_output_write_history(this, n, time, step, energies, probe_u, probe_v, stat, msg, &
      load_factor, iterations, residual)
    ! time(n), step(n), energies(5, n) (kinetic, strain, external_work, damping,
    ! balance_error), probe_u and probe_v (2, n_probes, n). A static run's file (analysis =
    ! 'static') also takes load_factor(n), iterations(n), residual(n) for /history/static,
    ! and only it. Rank 0 selects the data, the others select nothing, all take part in the
    ! extend and the write.
    class(h5_output_t), intent(inout) :: this
    integer, intent(in) :: n
    real(wp), intent(in) :: time(:), energies(:, :), probe_u(:, :, :), probe_v(:, :, :)
    integer(i8), intent(in) :: step(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    real(wp), intent(in), optional :: load_factor(:), residual(:)
    integer(i8), intent(in), optional :: iterations(:)
    real(wp), allocatable :: buf1(:), buf2(:, :)
    integer(HID_T) :: fspace, mspace
    integer(HSIZE_T) :: dims1(1), dims2(2)
    integer(i8) :: nn
    integer :: ierr, k, p, n_probes

    stat = 0
    msg = ''
    if (.not. this%is_open) then
      stat = 1
      msg = 'iem_h5_output: write_history on a file that is not open'
      return
    end if
    n_probes = size(this%probe_u_id)
    ! Same data on every rank, so these checks agree without communication.
    if (n < 0 .or. size(time) < n .or. size(step) < n .or. size(energies, 1) /= n_energies &
        .or. size(energies, 2) < n .or. size(probe_u, 1) /= 2 .or. size(probe_v, 1) /= 2 &
        .or. size(probe_u, 2) /= n_probes .or. size(probe_v, 2) /= n_probes &
        .or. size(probe_u, 3) < n .or. size(probe_v, 3) < n) then
      stat = 1
      msg = 'iem_h5_output: write_history: array shapes do not match n and the probes of ' &
        //this%path
      return
    end if
    if (this%static .neqv. (present(load_factor) .and. present(iterations) .and. &
        present(residual))) then
      stat = 1
      msg = 'iem_h5_output: write_history: load_factor, iterations and residual are needed '// &
        'for, and only for, the file of a static run ('//this%path//')'
      return
    end if
    if (this%static) then
      if (size(load_factor) < n .or. size(iterations) < n .or. size(residual) < n) then
        stat = 1
        msg = 'iem_h5_output: write_history: the static series are shorter than n ('// &
          this%path//')'
        return
      end if
    end if
    if (n == 0) return
    nn = int(n, i8)
    dims1 = [int(n, HSIZE_T)]
    dims2 = [2_HSIZE_T, int(n, HSIZE_T)]
    allocate (buf1(n), buf2(2, n))
    fspace = -1
    mspace = -1
    work: block
      call prepare_append(this, this%hist_time_id, '/history/time', 0, this%n_samples, nn, &
        fspace, mspace, stat, msg)
      if (stat /= 0) exit work
      buf1 = time(:n)
      call h5dwrite_f(this%hist_time_id, this%real_mtype, buf1, dims1, ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', '/history/time', stat, msg)) exit work
      call close_space(this, fspace, stat, msg)
      call close_space(this, mspace, stat, msg)

      call prepare_append(this, this%hist_step_id, '/history/step', 0, this%n_samples, nn, &
        fspace, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dwrite_f(this%hist_step_id, this%int_mtype, step(:n), dims1, ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', '/history/step', stat, msg)) exit work
      call close_space(this, fspace, stat, msg)
      call close_space(this, mspace, stat, msg)

      do k = 1, n_energies
        call prepare_append(this, this%energy_id(k), '/history/energy/'//trim(energy_names(k)), &
          0, this%n_samples, nn, fspace, mspace, stat, msg)
        if (stat /= 0) exit work
        buf1 = energies(k, :n)
        call h5dwrite_f(this%energy_id(k), this%real_mtype, buf1, dims1, ierr, mspace, fspace, &
          this%xfer_id)
        if (failed(this, ierr, 'h5dwrite_f', '/history/energy/'//trim(energy_names(k)), stat, &
          msg)) exit work
        call close_space(this, fspace, stat, msg)
        call close_space(this, mspace, stat, msg)
      end do

      do p = 1, n_probes
        call prepare_append(this, this%probe_u_id(p), trim(this%probe_path(p))// &
          '/displacement', 2, this%n_samples, nn, fspace, mspace, stat, msg)
        if (stat /= 0) exit work
        buf2 = probe_u(:, p, :n)
        call h5dwrite_f(this%probe_u_id(p), this%real_mtype, buf2, dims2, ierr, mspace, fspace, &
          this%xfer_id)
        if (failed(this, ierr, 'h5dwrite_f', trim(this%probe_path(p))//'/displacement', stat, &
          msg)) exit work
        call close_space(this, fspace, stat, msg)
        call close_space(this, mspace, stat, msg)

        call prepare_append(this, this%probe_v_id(p), trim(this%probe_path(p))//'/velocity', &
          2, this%n_samples, nn, fspace, mspace, stat, msg)
        if (stat /= 0) exit work
        buf2 = probe_v(:, p, :n)
        call h5dwrite_f(this%probe_v_id(p), this%real_mtype, buf2, dims2, ierr, mspace, fspace, &
          this%xfer_id)
        if (failed(this, ierr, 'h5dwrite_f', trim(this%probe_path(p))//'/velocity', stat, &
          msg)) exit work
        call close_space(this, fspace, stat, msg)
        call close_space(this, mspace, stat, msg)
      end do

      if (this%static) then
        do k = 1, n_static
          call prepare_append(this, this%static_id(k), '/history/static/'// &
            trim(static_names(k)), 0, this%n_samples, nn, fspace, mspace, stat, msg)
          if (stat /= 0) exit work
          select case (k)
          case (1)
            buf1 = load_factor(:n)
            call h5dwrite_f(this%static_id(k), this%real_mtype, buf1, dims1, ierr, mspace, &
              fspace, this%xfer_id)
          case (2)
            call h5dwrite_f(this%static_id(k), this%int_mtype, iterations(:n), dims1, ierr, &
              mspace, fspace, this%xfer_id)
          case default
            buf1 = residual(:n)
            call h5dwrite_f(this%static_id(k), this%real_mtype, buf1, dims1, ierr, mspace, &
              fspace, this%xfer_id)
          end select
          if (failed(this, ierr, 'h5dwrite_f', '/history/static/'//trim(static_names(k)), &
            stat, msg)) exit work
          call close_space(this, fspace, stat, msg)
          call close_space(this, mspace, stat, msg)
        end do
      end if
      call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
      if (failed(this, ierr, 'h5fflush_f', '/', stat, msg)) exit work
    end block work
    call close_space(this, fspace, stat, msg)
    call close_space(this, mspace, stat, msg)
    if (stat == 0) this%n_samples = this%n_samples + nn
  end subroutine h5_output_write_history

  !> Creates /history/springs/<name>/strain and /stress, (12, samples) each, for spring probes
  !> (the 12 springs of one cell: edges 1-4, Poisson springs 1-4, shear springs 1-4), with the
  !> cell's global index and the probe point as attributes; collective, same arguments on
  !> every rank, after create and before the first write_spring_history.
  subroutine h5_output_define_spring_probes(this, names, cell_gids, xy, stat, msg)
    class(h5_output_t), intent(inout) :: this
    character(len=*), intent(in) :: names(:)
    integer(i8), intent(in) :: cell_gids(:)
    real(wp), intent(in) :: xy(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(HID_T) :: gid, pgid
    integer :: ierr, p
    character(len=:), allocatable :: where
    character(len=*), parameter :: labels = 'edge1 edge2 edge3 edge4 poisson1 poisson2 '// &
      'poisson3 poisson4 shear1 shear2 shear3 shear4'

    stat = 0
    msg = ''
    if (.not. this%is_open) then
      stat = 1
      msg = 'iem_h5_output: define_spring_probes on a file that is not open'
      return
    end if
    if (allocated(this%spring_e_id)) deallocate(this%spring_e_id, this%spring_s_id)
    if (allocated(this%spring_path)) deallocate(this%spring_path)
    allocate(this%spring_e_id(size(names)), this%spring_s_id(size(names)))
    this%spring_e_id = -1
    this%spring_s_id = -1
    allocate(character(len=len('/history/springs/') + len(names)) :: &
      this%spring_path(size(names)))
    this%n_spring_samples = 0
    if (size(names) == 0) return
    gid = -1
    pgid = -1
    work: block
      call h5gcreate_f(this%file_id, '/history/springs', gid, ierr)
      if (failed(this, ierr, 'h5gcreate_f', '/history/springs', stat, msg)) exit work
      call put_attr(this, gid, '/history/springs', 'springs', stat, msg, text=labels)
      call put_attr(this, gid, '/history/springs', 'stress_definition', stat, msg, &
        text='spring modulus (Eq, Hq, Gq) times the normalised spring stress; strain: '// &
        'edge strain, sum of the two edge strains at the corner, corner shear measure')
      do p = 1, size(names)
        this%spring_path(p) = '/history/springs/'//trim(names(p))
        where = trim(this%spring_path(p))
        call h5gcreate_f(gid, trim(names(p)), pgid, ierr)
        if (failed(this, ierr, 'h5gcreate_f', where, stat, msg)) exit work
        call put_attr(this, pgid, where, 'cell', stat, msg, lval=cell_gids(p))
        call put_attr(this, pgid, where, 'x', stat, msg, rval=xy(1, p))
        call put_attr(this, pgid, where, 'y', stat, msg, rval=xy(2, p))
        call create_series(this, pgid, where//'/', 'strain', H5T_IEEE_F64LE, 12, &
          this%spring_e_id(p), stat, msg)
        call create_series(this, pgid, where//'/', 'stress', H5T_IEEE_F64LE, 12, &
          this%spring_s_id(p), stat, msg)
        if (stat /= 0) exit work
        call h5gclose_f(pgid, ierr)
        pgid = -1
        if (failed(this, ierr, 'h5gclose_f', where, stat, msg)) exit work
      end do
    end block work
    if (pgid >= 0) call h5gclose_f(pgid, ierr)
    if (gid >= 0) call h5gclose_f(gid, ierr)
  end subroutine h5_output_define_spring_probes

  !> Appends n samples of the spring probes: strain and stress (12, n_spring_probes, n),
  !> the same on every rank (rank 0 writes); collective.
  subroutine h5_output_write_spring_history(this, n, strain, stress, stat, msg)
    class(h5_output_t), intent(inout) :: this
    integer, intent(in) :: n
    real(wp), intent(in) :: strain(:, :, :), stress(:, :, :)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: p

    stat = 0
    msg = ''
    if (.not. allocated(this%spring_e_id) .or. n == 0) return
    if (size(strain, 1) /= 12 .or. size(strain, 2) /= size(this%spring_e_id) .or. &
        size(strain, 3) < n .or. any(shape(stress) /= shape(strain))) then
      stat = 1
      msg = 'iem_h5_output: write_spring_history: array shapes do not match the spring probes'
      return
    end if
    do p = 1, size(this%spring_e_id)
      call append_block(this, this%spring_e_id(p), trim(this%spring_path(p))//'/strain', &
        this%n_spring_samples, strain(:, p, :n), stat, msg)
      call append_block(this, this%spring_s_id(p), trim(this%spring_path(p))//'/stress', &
        this%n_spring_samples, stress(:, p, :n), stat, msg)
    end do
    if (stat == 0) this%n_spring_samples = this%n_spring_samples + n
  end subroutine h5_output_write_spring_history

  !> Writes a cell field, values(n) for this rank's cells in the order given to write_mesh,
  !> as /frames/<last frame>/<name> (n_cells values); collective, after write_frame.
  subroutine h5_output_write_cell_field(this, name, values, stat, msg)
    class(h5_output_t), intent(inout) :: this
    character(len=*), intent(in) :: name
    real(wp), intent(in) :: values(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: where, frame
    integer(HID_T) :: gid, did, fspace, mspace
    integer :: ierr

    stat = 0
    msg = ''
    if (.not. this%is_open .or. this%n_frames == 0 .or. .not. allocated(this%cell_start)) then
      stat = 1
      msg = 'iem_h5_output: write_cell_field needs an open file with its mesh and a frame'
      return
    end if
    frame = xdmf_frame_name(this%n_frames - 1)
    where = '/frames/'//frame//'/'//name
    gid = -1
    did = -1
    fspace = -1
    mspace = -1
    work: block
      call h5gopen_f(this%frames_id, frame, gid, ierr)
      if (failed(this, ierr, 'h5gopen_f', '/frames/'//frame, stat, msg)) exit work
      call h5screate_simple_f(1, [int(this%n_cells, HSIZE_T)], fspace, ierr)
      if (failed(this, ierr, 'h5screate_simple_f', where, stat, msg)) exit work
      call select_runs(this, fspace, where, 0, this%cell_start, this%cell_len, stat, msg)
      call make_mem_space(this, 0, size(values, kind=i8), where, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dcreate_f(gid, name, H5T_IEEE_F64LE, fspace, did, ierr, this%dcpl_id)
      if (failed(this, ierr, 'h5dcreate_f', where, stat, msg)) exit work
      call h5dwrite_f(did, this%real_mtype, values, [size(values, kind=HSIZE_T)], ierr, &
        mspace, fspace, this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', where, stat, msg)) exit work
    end block work
    if (did >= 0) call h5dclose_f(did, ierr)
    if (gid >= 0) call h5gclose_f(gid, ierr)
    call close_space(this, fspace, stat, msg)
    call close_space(this, mspace, stat, msg)
  end subroutine h5_output_write_cell_field

  !> Reopens the output of an interrupted dynamic run to append to it: keeps its first
  !> n_samples history samples and n_frames frames (later ones, written after the checkpoint
  !> the run continues from, are removed, so the history has no gap and no duplicate), marks
  !> it incomplete, and prepares this rank's node and cell selections as create and
  !> write_mesh do. Collective; the arguments as for create (probe and spring probe names
  !> must match the file).
  subroutine h5_output_reopen(this, path, comm, n_nodes, n_cells, owned_gids, cell_gids, &
      probe_names, spring_names, n_samples, n_frames, stat, msg)
    class(h5_output_t), intent(inout) :: this
    character(len=*), intent(in) :: path
    type(MPI_Comm), intent(in) :: comm
    integer(i8), intent(in) :: n_nodes, n_cells, n_samples, n_frames
    integer(i8), intent(in) :: owned_gids(:), cell_gids(:)
    character(len=*), intent(in) :: probe_names(:), spring_names(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(HID_T) :: fapl, attr
    integer :: ierr, k, p, zero
    integer(i8) :: have
    integer(HID_T) :: space
    logical :: exists
    character(len=:), allocatable :: pname, frame

    stat = 0
    msg = ''
    this%comm = comm
    call MPI_Comm_rank(comm, this%rank)
    call MPI_Comm_size(comm, this%n_ranks)
    this%path = path
    this%xmf_path = xdmf_path_of(path)
    this%h5_name = path(index(path, '/', back=.true.) + 1:)
    this%n_nodes = n_nodes
    this%n_cells = n_cells
    this%n_owned = size(owned_gids, kind=i8)
    this%static = .false.
    this%mesh_written = .true.
    call gid_runs(owned_gids, this%run_start, this%run_len)
    call gid_runs(cell_gids, this%cell_start, this%cell_len)
    if (allocated(this%probe_u_id)) deallocate (this%probe_u_id, this%probe_v_id)
    allocate (this%probe_u_id(size(probe_names)), this%probe_v_id(size(probe_names)))
    this%probe_u_id = -1
    this%probe_v_id = -1
    if (allocated(this%probe_path)) deallocate (this%probe_path)
    allocate (character(len=len('/history/probes/') + len(probe_names)) :: &
      this%probe_path(size(probe_names)))
    if (allocated(this%spring_e_id)) deallocate (this%spring_e_id, this%spring_s_id)
    if (allocated(this%spring_path)) deallocate (this%spring_path)
    allocate (this%spring_e_id(size(spring_names)), this%spring_s_id(size(spring_names)))
    this%spring_e_id = -1
    this%spring_s_id = -1
    allocate (character(len=len('/history/springs/') + len(spring_names)) :: &
      this%spring_path(size(spring_names)))
    fapl = -1
    attr = -1
    space = -1
    work: block
      call file_access_list(this, comm, fapl, stat, msg)
      if (stat /= 0) exit work
      call h5fopen_f(mpiio_name(path), H5F_ACC_RDWR_F, this%file_id, ierr, access_prp=fapl)
      if (failed(this, ierr, 'h5fopen_f', '/', stat, msg)) exit work
      this%is_open = .true.
      call dataset_lists(this, stat, msg)
      if (stat /= 0) exit work
      ! incomplete again until this run ends normally
      call h5aopen_f(this%file_id, 'complete', attr, ierr)
      if (failed(this, ierr, 'h5aopen_f', '/ attribute complete', stat, msg)) exit work
      zero = 0
      call h5awrite_f(attr, H5T_NATIVE_INTEGER, zero, one, ierr)
      if (failed(this, ierr, 'h5awrite_f', '/ attribute complete', stat, msg)) exit work

      ! the series, cut back to what the checkpoint covers
      call h5gopen_f(this%file_id, 'frames', this%frames_id, ierr)
      if (failed(this, ierr, 'h5gopen_f', '/frames', stat, msg)) exit work
      call open_series(this%frames_id, 'time', '/frames/time', 0, n_frames, this%frames_time_id)
      call open_series(this%frames_id, 'step', '/frames/step', 0, n_frames, this%frames_step_id)
      call open_series(this%file_id, 'history/time', '/history/time', 0, n_samples, &
                       this%hist_time_id)
      call open_series(this%file_id, 'history/step', '/history/step', 0, n_samples, &
                       this%hist_step_id)
      do k = 1, n_energies
        call open_series(this%file_id, 'history/energy/'//trim(energy_names(k)), &
          '/history/energy/'//trim(energy_names(k)), 0, n_samples, this%energy_id(k))
      end do
      do p = 1, size(probe_names)
        pname = trim(probe_names(p))
        this%probe_path(p) = '/history/probes/'//pname
        call open_series(this%file_id, 'history/probes/'//pname//'/displacement', &
          '/history/probes/'//pname//'/displacement', 2, n_samples, this%probe_u_id(p))
        call open_series(this%file_id, 'history/probes/'//pname//'/velocity', &
          '/history/probes/'//pname//'/velocity', 2, n_samples, this%probe_v_id(p))
      end do
      do p = 1, size(spring_names)
        pname = trim(spring_names(p))
        this%spring_path(p) = '/history/springs/'//pname
        call open_series(this%file_id, 'history/springs/'//pname//'/strain', &
          '/history/springs/'//pname//'/strain', 12, n_samples, this%spring_e_id(p))
        call open_series(this%file_id, 'history/springs/'//pname//'/stress', &
          '/history/springs/'//pname//'/stress', 12, n_samples, this%spring_s_id(p))
      end do
      if (stat /= 0) exit work
      this%n_samples = n_samples
      this%n_spring_samples = n_samples
      ! frames written after the checkpoint go
      have = n_frames
      do
        frame = xdmf_frame_name(have)
        call h5lexists_f(this%frames_id, frame, exists, ierr)
        if (failed(this, ierr, 'h5lexists_f', '/frames/'//frame, stat, msg)) exit work
        if (.not. exists) exit
        call h5ldelete_f(this%frames_id, frame, ierr)
        if (failed(this, ierr, 'h5ldelete_f', '/frames/'//frame, stat, msg)) exit work
        have = have + 1
      end do
      this%n_frames = n_frames
      ! frame times for the sidecar
      if (allocated(this%frame_times)) deallocate (this%frame_times)
      allocate (this%frame_times(max(16_i8, 2*n_frames)))
      if (n_frames > 0) then
        call h5dread_f(this%frames_time_id, this%real_mtype, this%frame_times(1:n_frames), &
          [int(n_frames, HSIZE_T)], ierr)
        if (failed(this, ierr, 'h5dread_f', '/frames/time', stat, msg)) exit work
      end if

      call h5screate_simple_f(2, [2_HSIZE_T, int(n_nodes, HSIZE_T)], this%node_fspace, ierr)
      if (failed(this, ierr, 'h5screate_simple_f', 'node file space', stat, msg)) exit work
      call select_runs(this, this%node_fspace, 'node file space', 2, this%run_start, &
        this%run_len, stat, msg)
      call make_mem_space(this, 2, this%n_owned, 'node memory space', this%node_mspace, &
        stat, msg)
    end block work
    if (attr >= 0) call h5aclose_f(attr, ierr)
    if (fapl >= 0) call h5pclose_f(fapl, ierr)
    if (stat /= 0) then
      if (this%is_open) then
        call release(this, k, pname)
      end if
      return
    end if
    call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
    call write_sidecar(this, stat, msg)

  contains

    !> Open an extendible series and cut it to n samples (it must hold at least n).
    subroutine open_series(loc, name, where, ncomp, n, dset)
      integer(HID_T), intent(in) :: loc
      character(len=*), intent(in) :: name, where
      integer, intent(in) :: ncomp
      integer(i8), intent(in) :: n
      integer(HID_T), intent(inout) :: dset
      integer :: rank, e
      integer(HSIZE_T) :: d(2), md(2)
      if (stat /= 0) return
      call h5dopen_f(loc, name, dset, e)
      if (failed(this, e, 'h5dopen_f', where, stat, msg)) return
      call h5dget_space_f(dset, space, e)
      if (failed(this, e, 'h5dget_space_f', where, stat, msg)) return
      call h5sget_simple_extent_dims_f(space, d, md, rank)
      call h5sclose_f(space, e)
      space = -1
      rank = merge(1, 2, ncomp == 0)
      if (d(rank) < int(n, HSIZE_T)) then
        stat = 1
        msg = 'iem_h5_output: '//path//': '//where//' holds '//itoa(int(d(rank), i8))// &
              ' entries, fewer than the '//itoa(n)//' the checkpoint needs'
        return
      end if
      if (ncomp == 0) then
        call h5dset_extent_f(dset, [int(n, HSIZE_T)], e)
      else
        call h5dset_extent_f(dset, [int(ncomp, HSIZE_T), int(n, HSIZE_T)], e)
      end if
      if (failed(this, e, 'h5dset_extent_f', where, stat, msg)) return
    end subroutine open_series
  end subroutine h5_output_reopen

  !> Adds /continuations/NNNN (1, 2, ...: one per continuation) with the attributes checkpoint
  !> (its path as given), time and step (where the run continued), n_ranks, date (the wall
  !> clock at the continuation, ISO 8601, of rank 0), samples and frames (what the file kept
  !> of the run before). Collective.
  subroutine h5_output_record_continuation(this, checkpoint, time, step, stat, msg)
    class(h5_output_t), intent(inout) :: this
    character(len=*), intent(in) :: checkpoint
    real(wp), intent(in) :: time
    integer(i8), intent(in) :: step
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(HID_T) :: grp, sub
    integer :: ierr, storage, max_corder, n_links, v(8)
    logical :: exists
    character(len=25) :: date
    character(len=4) :: name
    character(len=:), allocatable :: where

    stat = 0
    msg = ''
    grp = -1
    sub = -1
    where = '/continuations'
    date = ''
    if (this%rank == 0) then
      call date_and_time(values=v)
      write(date, '(i4.4,"-",i2.2,"-",i2.2,"T",i2.2,":",i2.2,":",i2.2,a1,i2.2,":",i2.2)') &
        v(1:3), v(5:7), merge('+', '-', v(4) >= 0), abs(v(4))/60, mod(abs(v(4)), 60)
    end if
    call MPI_Bcast(date, len(date), MPI_CHARACTER, 0, this%comm)
    work: block
      call h5lexists_f(this%file_id, 'continuations', exists, ierr)
      if (failed(this, ierr, 'h5lexists_f', '/continuations', stat, msg)) exit work
      if (exists) then
        call h5gopen_f(this%file_id, 'continuations', grp, ierr)
        if (failed(this, ierr, 'h5gopen_f', '/continuations', stat, msg)) exit work
      else
        call h5gcreate_f(this%file_id, 'continuations', grp, ierr)
        if (failed(this, ierr, 'h5gcreate_f', '/continuations', stat, msg)) exit work
      end if
      call h5gget_info_f(grp, storage, n_links, max_corder, ierr)
      if (failed(this, ierr, 'h5gget_info_f', '/continuations', stat, msg)) exit work
      write(name, '(i4.4)') n_links + 1
      where = '/continuations/'//name
      call h5gcreate_f(grp, name, sub, ierr)
      if (failed(this, ierr, 'h5gcreate_f', where, stat, msg)) exit work
      call put_attr(this, sub, where, 'checkpoint', stat, msg, text=checkpoint)
      call put_attr(this, sub, where, 'time', stat, msg, rval=time)
      call put_attr(this, sub, where, 'step', stat, msg, lval=step)
      call put_attr(this, sub, where, 'n_ranks', stat, msg, ival=this%n_ranks)
      call put_attr(this, sub, where, 'date', stat, msg, text=trim(date))
      call put_attr(this, sub, where, 'samples', stat, msg, lval=this%n_samples)
      call put_attr(this, sub, where, 'frames', stat, msg, lval=this%n_frames)
    end block work
    if (sub >= 0) then
      call h5gclose_f(sub, ierr)
      if (failed(this, ierr, 'h5gclose_f', where, stat, msg)) continue
    end if
    if (grp >= 0) then
      call h5gclose_f(grp, ierr)
      if (failed(this, ierr, 'h5gclose_f', '/continuations', stat, msg)) continue
    end if
    if (stat /= 0) return
    call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
    if (failed(this, ierr, 'h5fflush_f', '/', stat, msg)) return
  end subroutine h5_output_record_continuation

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

  !> Opens the HDF5 library if needed, sets the memory types, and makes the file access list
  !> for parallel I/O on comm with collective metadata (the caller closes fapl).
  subroutine file_access_list(this, comm, fapl, stat, msg)
    class(h5_output_t), intent(inout) :: this
    type(MPI_Comm), intent(in) :: comm
    integer(HID_T), intent(inout) :: fapl
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr
    if (.not. library_open) then
      call h5open_f(ierr)
      if (failed(this, ierr, 'h5open_f', 'the HDF5 library', stat, msg)) return
      library_open = .true.
    end if
    this%real_mtype = h5kind_to_type(wp, H5_REAL_KIND)
    this%int_mtype = h5kind_to_type(i8, H5_INTEGER_KIND)
    call h5pcreate_f(H5P_FILE_ACCESS_F, fapl, ierr)
    if (failed(this, ierr, 'h5pcreate_f', 'file access list', stat, msg)) return
    call h5pset_fapl_mpio_f(fapl, comm%MPI_VAL, MPI_INFO_NULL%MPI_VAL, ierr)
    if (failed(this, ierr, 'h5pset_fapl_mpio_f', 'file access list', stat, msg)) return
    ! 1.8 file format or later: compact/dense groups (many frames) and large attributes
    ! (input_text above 64 KiB); still readable by any HDF5 since 1.8.
    call h5pset_libver_bounds_f(fapl, H5F_LIBVER_V18_F, H5F_LIBVER_LATEST_F, ierr)
    if (failed(this, ierr, 'h5pset_libver_bounds_f', 'file access list', stat, msg)) return
    call h5pset_all_coll_metadata_ops_f(fapl, .true., ierr)
    if (failed(this, ierr, 'h5pset_all_coll_metadata_ops_f', 'file access list', stat, msg)) &
      return
    call h5pset_coll_metadata_write_f(fapl, .true., ierr)
    if (failed(this, ierr, 'h5pset_coll_metadata_write_f', 'file access list', stat, msg)) &
      return
  end subroutine file_access_list

  !> The collective transfer list and the dataset creation list (no fill values: every
  !> element of every dataset is written) of an open file.
  subroutine dataset_lists(this, stat, msg)
    class(h5_output_t), intent(inout) :: this
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr
    call h5pcreate_f(H5P_DATASET_XFER_F, this%xfer_id, ierr)
    if (failed(this, ierr, 'h5pcreate_f', 'transfer list', stat, msg)) return
    call h5pset_dxpl_mpio_f(this%xfer_id, H5FD_MPIO_COLLECTIVE_F, ierr)
    if (failed(this, ierr, 'h5pset_dxpl_mpio_f', 'transfer list', stat, msg)) return
    call h5pcreate_f(H5P_DATASET_CREATE_F, this%dcpl_id, ierr)
    if (failed(this, ierr, 'h5pcreate_f', 'dataset creation list', stat, msg)) return
    call h5pset_fill_time_f(this%dcpl_id, H5D_FILL_TIME_NEVER_F, ierr)
    if (failed(this, ierr, 'h5pset_fill_time_f', 'dataset creation list', stat, msg)) return
  end subroutine dataset_lists

  !> Appends the samples data(ncomp, n) to the extendible series dset after its first `old`
  !> samples (rank 0 writes; collective). Does nothing once stat /= 0.
  subroutine append_block(this, dset, where, old, data, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: dset
    character(len=*), intent(in) :: where
    integer(i8), intent(in) :: old
    real(wp), intent(in) :: data(:, :)
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    real(wp), allocatable :: buf(:, :)
    integer(HID_T) :: fspace, mspace
    integer :: ierr
    if (stat /= 0) return
    fspace = -1
    mspace = -1
    buf = data
    call prepare_append(this, dset, where, size(data, 1), old, size(data, 2, kind=i8), fspace, &
      mspace, stat, msg)
    if (stat == 0) then
      call h5dwrite_f(dset, this%real_mtype, buf, shape(buf, HSIZE_T), ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this, ierr, 'h5dwrite_f', where, stat, msg)) continue
    end if
    call close_space(this, fspace, stat, msg)
    call close_space(this, mspace, stat, msg)
  end subroutine append_block

  !> Writes the settings of a static run as attributes of /history/static; collective, the
  !> same values on every rank.
  subroutine h5_output_write_static_settings(this, load_steps, tolerance, max_iterations, &
      method, mass, check_interval, stat, msg)
    class(h5_output_t), intent(inout) :: this
    integer, intent(in) :: load_steps, max_iterations, check_interval
    real(wp), intent(in) :: tolerance
    character(len=*), intent(in) :: method, mass
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(HID_T) :: gid
    integer :: ierr
    character(len=*), parameter :: where = '/history/static'

    stat = 0
    msg = ''
    if (.not. (this%is_open .and. this%static)) then
      stat = 1
      msg = 'iem_h5_output: write_static_settings needs the open file of a static run'
      return
    end if
    call h5gopen_f(this%file_id, 'history/static', gid, ierr)
    if (failed(this, ierr, 'h5gopen_f', where, stat, msg)) return
    call put_attr(this, gid, where, 'load_steps', stat, msg, ival=load_steps)
    call put_attr(this, gid, where, 'tolerance', stat, msg, rval=tolerance)
    call put_attr(this, gid, where, 'max_iterations', stat, msg, ival=max_iterations)
    call put_attr(this, gid, where, 'method', stat, msg, text=method)
    call put_attr(this, gid, where, 'mass', stat, msg, text=mass)
    call put_attr(this, gid, where, 'check_interval', stat, msg, ival=check_interval)
    call h5gclose_f(gid, ierr)
    if (failed(this, ierr, 'h5gclose_f', where, stat, msg)) return
  end subroutine h5_output_write_static_settings

  !> Closes the file collectively, after setting complete = 1 as the last write if `complete`.
  subroutine h5_output_close(this, complete, stat, msg)
    ! Rank 0 then rewrites the sidecar. Does nothing if the file is not open (never created,
    ! failed create, closed already).
    class(h5_output_t), intent(inout) :: this
    logical, intent(in) :: complete
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(HID_T) :: attr
    integer :: ierr, one_value

    stat = 0
    msg = ''
    if (.not. this%is_open) return
    call release_objects(this, stat, msg)
    if (complete .and. stat == 0) then
      ! Everything else reaches the file before the marker does.
      attr = -1
      work: block
        call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
        if (failed(this, ierr, 'h5fflush_f', '/', stat, msg)) exit work
        call h5aopen_f(this%file_id, 'complete', attr, ierr)
        if (failed(this, ierr, 'h5aopen_f', '/ attribute complete', stat, msg)) exit work
        one_value = 1
        call h5awrite_f(attr, H5T_NATIVE_INTEGER, one_value, one, ierr)
        if (failed(this, ierr, 'h5awrite_f', '/ attribute complete', stat, msg)) exit work
      end block work
      if (attr >= 0) then
        call h5aclose_f(attr, ierr)
        if (failed(this, ierr, 'h5aclose_f', '/ attribute complete', stat, msg)) continue
      end if
    end if
    call h5fclose_f(this%file_id, ierr)
    if (failed(this, ierr, 'h5fclose_f', '/', stat, msg)) continue
    this%file_id = -1
    this%is_open = .false.
    call write_sidecar(this, stat, msg)
  end subroutine h5_output_close

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

  ! ---- helpers ------------------------------------------------------------------------------

  !> True if ierr reports an HDF5 failure; records the first failure in stat and msg.
  logical function failed(this, ierr, call_name, object, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer, intent(in) :: ierr
    character(len=*), intent(in) :: call_name, object
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg

    failed = ierr /= 0
    if (failed .and. stat == 0) then
      stat = 1
      msg = 'iem_h5_output: '//call_name//' failed on '//object//' in '//this%path
    end if
  end function failed

  !> Rank 0 rewrites the sidecar with the frames written so far; collective, so that every
  !> rank learns of a failure (then stat = h5_output_sidecar_error unless already set).
  subroutine write_sidecar(this, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    character(len=:), allocatable :: xmsg
    integer :: xstat

    xstat = 0
    if (this%rank == 0 .and. stat == 0) then
      call xdmf_write(this%xmf_path, this%h5_name, this%n_nodes, this%n_cells, &
        this%frame_times(:this%n_frames), xstat, xmsg)
    end if
    call MPI_Bcast(xstat, 1, MPI_INTEGER, 0, this%comm)
    if (xstat == 0 .or. stat /= 0) return
    stat = h5_output_sidecar_error
    if (this%rank == 0) then
      msg = xmsg
    else
      msg = 'iem_h5_output: rank 0 could not write the sidecar '//this%xmf_path
    end if
  end subroutine write_sidecar

  !> Creates and writes the scalar attribute `name` of object `loc` (called `where` in
  !> messages) from whichever of text, ival, lval, rval is present. No-op if stat /= 0.
  subroutine put_attr(this, loc, where, name, stat, msg, text, ival, lval, rval)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: loc
    character(len=*), intent(in) :: where, name
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    character(len=*), intent(in), optional :: text
    integer, intent(in), optional :: ival
    integer(i8), intent(in), optional :: lval
    real(wp), intent(in), optional :: rval
    character(len=:), allocatable :: obj
    integer(HID_T) :: space, ftype, mtype, attr
    integer :: ierr
    logical :: own_type

    if (stat /= 0) return
    obj = where//' attribute '//name
    space = -1
    attr = -1
    own_type = .false.
    work: block
      call h5screate_f(H5S_SCALAR_F, space, ierr)
      if (failed(this, ierr, 'h5screate_f', obj, stat, msg)) exit work
      if (present(text)) then
        ! Fixed-length, null-padded; the same type in memory and file, so bytes go verbatim.
        call h5tcopy_f(H5T_FORTRAN_S1, ftype, ierr)
        if (failed(this, ierr, 'h5tcopy_f', obj, stat, msg)) exit work
        own_type = .true.
        call h5tset_size_f(ftype, int(max(len(text), 1), SIZE_T), ierr)
        if (failed(this, ierr, 'h5tset_size_f', obj, stat, msg)) exit work
        call h5tset_strpad_f(ftype, H5T_STR_NULLPAD_F, ierr)
        if (failed(this, ierr, 'h5tset_strpad_f', obj, stat, msg)) exit work
        mtype = ftype
      else if (present(ival)) then
        ftype = H5T_STD_I32LE
        mtype = H5T_NATIVE_INTEGER
      else if (present(lval)) then
        ftype = H5T_STD_I64LE
        mtype = this%int_mtype
      else
        ftype = H5T_IEEE_F64LE
        mtype = this%real_mtype
      end if
      call h5acreate_f(loc, name, ftype, space, attr, ierr)
      if (failed(this, ierr, 'h5acreate_f', obj, stat, msg)) exit work
      if (present(text)) then
        if (len(text) == 0) then
          call h5awrite_f(attr, mtype, achar(0), one, ierr)
        else
          call h5awrite_f(attr, mtype, text, one, ierr)
        end if
      else if (present(ival)) then
        call h5awrite_f(attr, mtype, ival, one, ierr)
      else if (present(lval)) then
        call h5awrite_f(attr, mtype, lval, one, ierr)
      else if (present(rval)) then
        call h5awrite_f(attr, mtype, rval, one, ierr)
      else
        ierr = -1
      end if
      if (failed(this, ierr, 'h5awrite_f', obj, stat, msg)) exit work
    end block work
    if (attr >= 0) then
      call h5aclose_f(attr, ierr)
      if (failed(this, ierr, 'h5aclose_f', obj, stat, msg)) continue
    end if
    if (own_type) then
      call h5tclose_f(ftype, ierr)
      if (failed(this, ierr, 'h5tclose_f', obj, stat, msg)) continue
    end if
    call close_space(this, space, stat, msg)
  end subroutine put_attr

  !> Creates the empty, extendible, chunked dataset `name` in `loc`: 1-D if ncomp == 0, else
  !> (ncomp, unlimited) in Fortran order. No-op if stat /= 0.
  subroutine create_series(this, loc, where, name, ftype, ncomp, dset, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: loc, ftype
    character(len=*), intent(in) :: where, name
    integer, intent(in) :: ncomp
    integer(HID_T), intent(inout) :: dset
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer(HSIZE_T) :: dims(2), maxdims(2), chunk(2)
    integer(HID_T) :: space, dcpl
    integer :: rank, ierr

    if (stat /= 0) return
    if (ncomp == 0) then
      rank = 1
      dims(1) = 0
      maxdims(1) = H5S_UNLIMITED_F
      chunk(1) = series_chunk
    else
      rank = 2
      dims = [int(ncomp, HSIZE_T), 0_HSIZE_T]
      maxdims = [int(ncomp, HSIZE_T), H5S_UNLIMITED_F]
      chunk = [int(ncomp, HSIZE_T), series_chunk]
    end if
    space = -1
    dcpl = -1
    work: block
      call h5screate_simple_f(rank, dims(:rank), space, ierr, maxdims(:rank))
      if (failed(this, ierr, 'h5screate_simple_f', where//name, stat, msg)) exit work
      call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, ierr)
      if (failed(this, ierr, 'h5pcreate_f', where//name, stat, msg)) exit work
      call h5pset_chunk_f(dcpl, rank, chunk(:rank), ierr)
      if (failed(this, ierr, 'h5pset_chunk_f', where//name, stat, msg)) exit work
      call h5pset_fill_time_f(dcpl, H5D_FILL_TIME_NEVER_F, ierr)
      if (failed(this, ierr, 'h5pset_fill_time_f', where//name, stat, msg)) exit work
      call h5dcreate_f(loc, name, ftype, space, dset, ierr, dcpl)
      if (failed(this, ierr, 'h5dcreate_f', where//name, stat, msg)) exit work
    end block work
    if (dcpl >= 0) then
      call h5pclose_f(dcpl, ierr)
      if (failed(this, ierr, 'h5pclose_f', where//name, stat, msg)) continue
    end if
    call close_space(this, space, stat, msg)
  end subroutine create_series

  !> Extends `dset` from `old` to `old + n` samples (ncomp components each, 0: 1-D) and
  !> returns a file space with the new samples selected on rank 0 (none elsewhere) and a
  !> matching memory space of n samples.
  subroutine prepare_append(this, dset, where, ncomp, old, n, fspace, mspace, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: dset
    character(len=*), intent(in) :: where
    integer, intent(in) :: ncomp
    integer(i8), intent(in) :: old, n
    integer(HID_T), intent(inout) :: fspace, mspace
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer(HSIZE_T) :: new_dims(2), start(2), count(2)
    integer :: rank, ierr

    if (stat /= 0) return
    if (ncomp == 0) then
      rank = 1
      new_dims(1) = int(old + n, HSIZE_T)
      start(1) = int(old, HSIZE_T)
      count(1) = int(n, HSIZE_T)
    else
      rank = 2
      new_dims = [int(ncomp, HSIZE_T), int(old + n, HSIZE_T)]
      start = [0_HSIZE_T, int(old, HSIZE_T)]
      count = [int(ncomp, HSIZE_T), int(n, HSIZE_T)]
    end if
    call h5dset_extent_f(dset, new_dims(:rank), ierr)
    if (failed(this, ierr, 'h5dset_extent_f', where, stat, msg)) return
    call h5dget_space_f(dset, fspace, ierr)
    if (failed(this, ierr, 'h5dget_space_f', where, stat, msg)) return
    call h5screate_simple_f(rank, count(:rank), mspace, ierr)
    if (failed(this, ierr, 'h5screate_simple_f', where, stat, msg)) return
    if (this%rank == 0) then
      call h5sselect_hyperslab_f(fspace, H5S_SELECT_SET_F, start(:rank), count(:rank), ierr)
      if (failed(this, ierr, 'h5sselect_hyperslab_f', where, stat, msg)) return
    else
      call h5sselect_none_f(fspace, ierr)
      if (failed(this, ierr, 'h5sselect_none_f', where, stat, msg)) return
      call h5sselect_none_f(mspace, ierr)
      if (failed(this, ierr, 'h5sselect_none_f', where, stat, msg)) return
    end if
  end subroutine prepare_append

  !> Creates the node dataset `name` (2, n_nodes) in group `gid` and writes this rank's nodes
  !> from field(2, n_owned); if not shapes_ok, writes nothing but takes part. No-op if stat /= 0.
  subroutine write_node_field(this, gid, where, name, field, shapes_ok, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: gid
    character(len=*), intent(in) :: where, name
    real(wp), intent(in) :: field(:, :)
    logical, intent(in) :: shapes_ok
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    real(wp) :: dummy(2, 1)
    integer(HID_T) :: did, fspace, mspace
    integer :: ierr

    if (stat /= 0) return
    did = -1
    fspace = -1
    mspace = -1
    work: block
      call h5dcreate_f(gid, name, H5T_IEEE_F64LE, this%node_fspace, did, ierr, this%dcpl_id)
      if (failed(this, ierr, 'h5dcreate_f', where, stat, msg)) exit work
      if (shapes_ok) then
        call h5dwrite_f(did, this%real_mtype, field, shape(field, HSIZE_T), ierr, &
          this%node_mspace, this%node_fspace, this%xfer_id)
      else
        call h5scopy_f(this%node_fspace, fspace, ierr)
        if (failed(this, ierr, 'h5scopy_f', where, stat, msg)) exit work
        call h5sselect_none_f(fspace, ierr)
        if (failed(this, ierr, 'h5sselect_none_f', where, stat, msg)) exit work
        call make_mem_space(this, 2, 0_i8, where, mspace, stat, msg)
        if (stat /= 0) exit work
        dummy = 0
        call h5dwrite_f(did, this%real_mtype, dummy, shape(dummy, HSIZE_T), ierr, mspace, &
          fspace, this%xfer_id)
      end if
      if (failed(this, ierr, 'h5dwrite_f', where, stat, msg)) exit work
    end block work
    if (did >= 0) then
      call h5dclose_f(did, ierr)
      if (failed(this, ierr, 'h5dclose_f', where, stat, msg)) continue
    end if
    call close_space(this, fspace, stat, msg)
    call close_space(this, mspace, stat, msg)
  end subroutine write_node_field

  !> Selects in `space` the entries of the gid runs (starts 0-based, lengths): 1-D if
  !> ncomp == 0, else the whole first dimension of (ncomp, n). No-op if stat /= 0.
  subroutine select_runs(this, space, where, ncomp, starts, lens, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: space
    character(len=*), intent(in) :: where
    integer, intent(in) :: ncomp
    integer(i8), intent(in) :: starts(:), lens(:)
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    if (stat /= 0) return
    if (size(starts) == 0) then
      call h5sselect_none_f(space, ierr)
      if (failed(this, ierr, 'h5sselect_none_f', where, stat, msg)) return
    else
      call select_run_range(this, space, where, ncomp, starts, lens, 1, size(starts), stat, msg)
    end if
  end subroutine select_runs

  !> Selects in `space` (whose selection is replaced) the runs lo..hi, as select_runs.
  !>
  !> Adding the runs one by one with H5S_SELECT_OR costs time proportional to the selection
  !> built so far in HDF5 1.10 (minutes for 50 000 runs); halving the range and merging the two
  !> halves with H5Smodify_select makes it O(n log n) (0.06 s for 50 000 runs).
  recursive subroutine select_run_range(this, space, where, ncomp, starts, lens, lo, hi, &
      stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: space
    character(len=*), intent(in) :: where
    integer, intent(in) :: ncomp, lo, hi
    integer(i8), intent(in) :: starts(:), lens(:)
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer, parameter :: leaf_runs = 16
    integer(HSIZE_T) :: start(2), count(2)
    integer(HID_T) :: upper
    integer :: r, op, ierr, rank, mid

    if (stat /= 0) return
    if (hi - lo < leaf_runs) then
      rank = merge(1, 2, ncomp == 0)
      do r = lo, hi
        op = merge(H5S_SELECT_SET_F, H5S_SELECT_OR_F, r == lo)
        if (ncomp == 0) then
          start(1) = int(starts(r), HSIZE_T)
          count(1) = int(lens(r), HSIZE_T)
        else
          start = [0_HSIZE_T, int(starts(r), HSIZE_T)]
          count = [int(ncomp, HSIZE_T), int(lens(r), HSIZE_T)]
        end if
        call h5sselect_hyperslab_f(space, op, start(:rank), count(:rank), ierr)
        if (failed(this, ierr, 'h5sselect_hyperslab_f', where, stat, msg)) return
      end do
      return
    end if
    mid = lo + (hi - lo)/2
    ! Copied before `space` gets a selection, so that copies stay cheap.
    call h5scopy_f(space, upper, ierr)
    if (failed(this, ierr, 'h5scopy_f', where, stat, msg)) return
    call select_run_range(this, space, where, ncomp, starts, lens, lo, mid, stat, msg)
    call select_run_range(this, upper, where, ncomp, starts, lens, mid + 1, hi, stat, msg)
    if (stat == 0) then
      ierr = h5s_modify_select(int(space, c_int64_t), int(H5S_SELECT_OR_F, c_int), &
        int(upper, c_int64_t))
      if (failed(this, merge(-1, 0, ierr < 0), 'H5Smodify_select', where, stat, msg)) continue
    end if
    call close_space(this, upper, stat, msg)
  end subroutine select_run_range

  !> Memory space of n entries of ncomp components (0: 1-D); with nothing selected if n == 0.
  !> No-op if stat /= 0.
  subroutine make_mem_space(this, ncomp, n, where, space, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer, intent(in) :: ncomp
    integer(i8), intent(in) :: n
    character(len=*), intent(in) :: where
    integer(HID_T), intent(inout) :: space
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    if (stat /= 0) return
    if (n == 0) then
      call h5screate_f(H5S_SCALAR_F, space, ierr)
      if (failed(this, ierr, 'h5screate_f', where, stat, msg)) return
      call h5sselect_none_f(space, ierr)
      if (failed(this, ierr, 'h5sselect_none_f', where, stat, msg)) return
    else if (ncomp == 0) then
      call h5screate_simple_f(1, [int(n, HSIZE_T)], space, ierr)
      if (failed(this, ierr, 'h5screate_simple_f', where, stat, msg)) return
    else
      call h5screate_simple_f(2, [int(ncomp, HSIZE_T), int(n, HSIZE_T)], space, ierr)
      if (failed(this, ierr, 'h5screate_simple_f', where, stat, msg)) return
    end if
  end subroutine make_mem_space

  !> Closes dataspace `space` if open and marks it closed; records a failure in stat, msg.
  subroutine close_space(this, space, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(inout) :: space
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    if (space < 0) return
    call h5sclose_f(space, ierr)
    space = -1
    if (failed(this, ierr, 'h5sclose_f', 'a dataspace', stat, msg)) continue
  end subroutine close_space

  !> Closes dataset `dset` if open and marks it closed; records a failure in stat, msg.
  subroutine close_dset(this, dset, where, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(inout) :: dset
    character(len=*), intent(in) :: where
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    if (dset < 0) return
    call h5dclose_f(dset, ierr)
    dset = -1
    if (failed(this, ierr, 'h5dclose_f', where, stat, msg)) continue
  end subroutine close_dset

  !> Closes every open object of the file except the file itself; keeps the first error.
  subroutine release_objects(this, stat, msg)
    class(h5_output_t), intent(inout) :: this
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr, k

    call close_dset(this, this%frames_time_id, '/frames/time', stat, msg)
    call close_dset(this, this%frames_step_id, '/frames/step', stat, msg)
    call close_dset(this, this%hist_time_id, '/history/time', stat, msg)
    call close_dset(this, this%hist_step_id, '/history/step', stat, msg)
    do k = 1, n_energies
      call close_dset(this, this%energy_id(k), '/history/energy/'//trim(energy_names(k)), &
        stat, msg)
    end do
    do k = 1, n_static
      call close_dset(this, this%static_id(k), '/history/static/'//trim(static_names(k)), &
        stat, msg)
    end do
    if (allocated(this%probe_u_id)) then
      do k = 1, size(this%probe_u_id)
        call close_dset(this, this%probe_u_id(k), trim(this%probe_path(k))//'/displacement', &
          stat, msg)
        call close_dset(this, this%probe_v_id(k), trim(this%probe_path(k))//'/velocity', stat, &
          msg)
      end do
    end if
    if (allocated(this%spring_e_id)) then
      do k = 1, size(this%spring_e_id)
        call close_dset(this, this%spring_e_id(k), trim(this%spring_path(k))//'/strain', stat, &
          msg)
        call close_dset(this, this%spring_s_id(k), trim(this%spring_path(k))//'/stress', stat, &
          msg)
      end do
      deallocate(this%spring_e_id, this%spring_s_id)
    end if
    if (this%frames_id >= 0) then
      call h5gclose_f(this%frames_id, ierr)
      this%frames_id = -1
      if (failed(this, ierr, 'h5gclose_f', '/frames', stat, msg)) continue
    end if
    call close_space(this, this%node_fspace, stat, msg)
    call close_space(this, this%node_mspace, stat, msg)
    if (this%xfer_id >= 0) then
      call h5pclose_f(this%xfer_id, ierr)
      this%xfer_id = -1
      if (failed(this, ierr, 'h5pclose_f', 'transfer list', stat, msg)) continue
    end if
    if (this%dcpl_id >= 0) then
      call h5pclose_f(this%dcpl_id, ierr)
      this%dcpl_id = -1
      if (failed(this, ierr, 'h5pclose_f', 'dataset creation list', stat, msg)) continue
    end if
  end subroutine release_objects

  !> Closes every open object and the file, after a failure; keeps the first error.
  subroutine release(this, stat, msg)
    class(h5_output_t), intent(inout) :: this
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr

    call release_objects(this, stat, msg)
    if (this%file_id >= 0) then
      call h5fclose_f(this%file_id, ierr)
      this%file_id = -1
      if (failed(this, ierr, 'h5fclose_f', '/', stat, msg)) continue
    end if
    this%is_open = .false.
  end subroutine release

  !> Contiguous runs of strictly ascending ids: first id and length of each.
  pure subroutine gid_runs(gids, starts, lens)
    integer(i8), intent(in) :: gids(:)
    integer(i8), allocatable, intent(out) :: starts(:), lens(:)
    integer(i8) :: k, n, r

    n = size(gids, kind=i8)
    if (n == 0) then
      allocate (starts(0), lens(0))
      return
    end if
    allocate (starts(1 + count(gids(2:) /= gids(:n - 1) + 1)))
    allocate (lens(size(starts)))
    r = 1
    starts(1) = gids(1)
    lens(1) = 1
    do k = 2, n
      if (gids(k) == gids(k - 1) + 1) then
        lens(r) = lens(r) + 1
      else
        r = r + 1
        starts(r) = gids(k)
        lens(r) = 1
      end if
    end do
  end subroutine gid_runs

  !> Empty if the arguments of create are consistent on this rank, else what is wrong.
  function check_create_args(n_nodes, n_cells, owned_gids, probe_names, probe_xy, probe_node, &
      probe_node_xy) result(err)
    integer(i8), intent(in) :: n_nodes, n_cells, owned_gids(:), probe_node(:)
    character(len=*), intent(in) :: probe_names(:)
    real(wp), intent(in) :: probe_xy(:, :), probe_node_xy(:, :)
    character(len=:), allocatable :: err
    character(len=:), allocatable :: pname
    integer :: n_probes, p, q

    err = ''
    n_probes = size(probe_names)
    if (n_nodes < 1 .or. n_cells < 1) then
      err = 'n_nodes and n_cells must be positive'
    else if (size(owned_gids) > 0) then
      if (owned_gids(1) < 0 .or. owned_gids(size(owned_gids)) >= n_nodes) then
        err = 'owned_gids out of 0..n_nodes-1'
      else if (any(owned_gids(2:) <= owned_gids(:size(owned_gids) - 1))) then
        err = 'owned_gids not strictly ascending'
      end if
    end if
    if (len(err) > 0) return
    if (size(probe_xy, 1) /= 2 .or. size(probe_xy, 2) /= n_probes .or. &
        size(probe_node) /= n_probes .or. size(probe_node_xy, 1) /= 2 .or. &
        size(probe_node_xy, 2) /= n_probes) then
      err = 'probe_xy, probe_node, probe_node_xy do not match probe_names'
      return
    end if
    if (any(probe_node < 0 .or. probe_node >= n_nodes)) then
      err = 'probe_node out of 0..n_nodes-1'
      return
    end if
    do p = 1, n_probes
      pname = trim(probe_names(p))
      if (len(pname) == 0 .or. pname == '.' .or. index(pname, '/') > 0) then
        err = 'probe name "'//pname//'" is not a valid HDF5 group name'
        return
      end if
      do q = 1, p - 1
        if (trim(probe_names(q)) == pname) then
          err = 'probe name "'//pname//'" given twice'
          return
        end if
      end do
    end do
  end function check_create_args

  !> Empty if the arguments of write_mesh are consistent on this rank, else what is wrong.
  function check_mesh_args(this, coords, mass, cells, cell_gids) result(err)
    class(h5_output_t), intent(in) :: this
    real(wp), intent(in) :: coords(:, :), mass(:)
    integer(i8), intent(in) :: cells(:, :), cell_gids(:)
    character(len=:), allocatable :: err
    integer :: n

    err = ''
    n = size(cell_gids)
    if (size(coords, 1) /= 2 .or. size(coords, 2, kind=i8) /= this%n_owned .or. &
        size(mass, kind=i8) /= this%n_owned) then
      err = 'coords and mass must be (2, n_owned) and (n_owned)'
    else if (size(cells, 1) /= 4 .or. size(cells, 2) /= n) then
      err = 'cells must be (4, size(cell_gids))'
    else if (n > 0) then
      if (cell_gids(1) < 0 .or. cell_gids(n) >= this%n_cells) then
        err = 'cell_gids out of 0..n_cells-1'
      else if (any(cell_gids(2:) <= cell_gids(:n - 1))) then
        err = 'cell_gids not strictly ascending'
      else if (any(cells < 0 .or. cells >= this%n_nodes)) then
        err = 'cells hold node ids out of 0..n_nodes-1'
      end if
    end if
  end function check_mesh_args

end module iem_h5_output

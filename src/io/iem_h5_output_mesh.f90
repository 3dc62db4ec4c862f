!> /mesh: node coordinates and masses, cell corners, and the grid attributes.
submodule (iem_h5_output) iem_h5_output_mesh
  use iem_kinds, only: mpi_i8
  use iem_strings, only: itoa
  use mpi_f08, only: MPI_Allreduce, MPI_INTEGER, MPI_MAX, MPI_SUM
  use hdf5, only: HSIZE_T, h5fflush_f, H5F_SCOPE_GLOBAL_F, h5gopen_f, h5gclose_f, h5dcreate_f, &
    h5dwrite_f, h5dclose_f, h5screate_simple_f, H5T_STD_I64LE, H5T_IEEE_F64LE
  use iem_h5_primitives, only: failed, put_attr, select_runs, make_mem_space, close_space, &
    gid_runs
  implicit none

contains

  !> Writes /mesh and its attributes collectively, each rank its owned nodes and its cells.
  module procedure h5_output_write_mesh
    ! coords(2, n_owned), mass(n_owned) in owned_gids order; cells(4, n): 0-based global corner
    ! ids of the cells at the 0-based global, strictly ascending indices cell_gids(n); every
    ! cell is written by exactly one rank.
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
    if (present(coords) .eqv. this%coords_written) then
      stat = 1
      msg = 'iem_h5_output: write_mesh needs the coordinates exactly once (coords or '// &
        'write_mesh_coordinates) for '//this%path
      return
    end if
    n_my_cells = size(cell_gids, kind=i8)
    local_msg = check_mesh_args(this, mass, cells, cell_gids, coords)
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
      if (failed(this%path, ierr, 'h5gopen_f', '/mesh', stat, msg)) exit work

      if (present(coords)) then
        call write_coordinates(this, gid, coords, stat, msg)
        if (stat /= 0) exit work
      end if

      call h5screate_simple_f(2, [4_HSIZE_T, int(this%n_cells, HSIZE_T)], cell_fspace, ierr)
      if (failed(this%path, ierr, 'h5screate_simple_f', '/mesh/cells', stat, msg)) exit work
      call select_runs(this%path, cell_fspace, '/mesh/cells', 4, cstart, clen, stat, msg)
      call make_mem_space(this%path, 4, n_my_cells, '/mesh/cells', cell_mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dcreate_f(gid, 'cells', H5T_STD_I64LE, cell_fspace, did, ierr, this%dcpl_id)
      if (failed(this%path, ierr, 'h5dcreate_f', '/mesh/cells', stat, msg)) exit work
      call h5dwrite_f(did, this%int_mtype, cells, shape(cells, HSIZE_T), ierr, cell_mspace, &
        cell_fspace, this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', '/mesh/cells', stat, msg)) exit work
      call h5dclose_f(did, ierr)
      did = -1
      if (failed(this%path, ierr, 'h5dclose_f', '/mesh/cells', stat, msg)) exit work

      call h5screate_simple_f(1, [int(this%n_nodes, HSIZE_T)], mass_fspace, ierr)
      if (failed(this%path, ierr, 'h5screate_simple_f', '/mesh/mass', stat, msg)) exit work
      call select_runs(this%path, mass_fspace, '/mesh/mass', 0, this%run_start, this%run_len, &
        stat, msg)
      call make_mem_space(this%path, 0, this%n_owned, '/mesh/mass', mass_mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dcreate_f(gid, 'mass', H5T_IEEE_F64LE, mass_fspace, did, ierr, this%dcpl_id)
      if (failed(this%path, ierr, 'h5dcreate_f', '/mesh/mass', stat, msg)) exit work
      call h5dwrite_f(did, this%real_mtype, mass, shape(mass, HSIZE_T), ierr, mass_mspace, &
        mass_fspace, this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', '/mesh/mass', stat, msg)) exit work
      call h5dclose_f(did, ierr)
      did = -1
      if (failed(this%path, ierr, 'h5dclose_f', '/mesh/mass', stat, msg)) exit work

      if (present(material)) then
        call write_cell_ints(gid, 'material', material)
        if (stat /= 0) exit work
        if (present(material_names)) call put_attr(this%path, gid, '/mesh', 'material_names', &
                                                   stat, msg, text=material_names)
      end if
      call put_attr(this%path, gid, '/mesh', 'nx', stat, msg, ival=nx)
      call put_attr(this%path, gid, '/mesh', 'ny', stat, msg, ival=ny)
      call put_attr(this%path, gid, '/mesh', 'lx', stat, msg, rval=lx)
      call put_attr(this%path, gid, '/mesh', 'ly', stat, msg, rval=ly)
      call put_attr(this%path, gid, '/mesh', 'thickness', stat, msg, rval=thickness)
      call put_attr(this%path, gid, '/mesh', 'plane', stat, msg, text=plane)
      if (stat /= 0) exit work
      call h5gclose_f(gid, ierr)
      gid = -1
      if (failed(this%path, ierr, 'h5gclose_f', '/mesh', stat, msg)) exit work
      call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
      if (failed(this%path, ierr, 'h5fflush_f', '/', stat, msg)) exit work
      this%mesh_written = .true.
    end block work

    tmp_stat = 0
    tmp_msg = ''
    if (did >= 0) call h5dclose_f(did, ierr)
    if (gid >= 0) call h5gclose_f(gid, ierr)
    call close_space(this%path, cell_fspace, tmp_stat, tmp_msg)
    call close_space(this%path, cell_mspace, tmp_stat, tmp_msg)
    call close_space(this%path, mass_fspace, tmp_stat, tmp_msg)
    call close_space(this%path, mass_mspace, tmp_stat, tmp_msg)
    if (stat == 0 .and. tmp_stat /= 0) then
      stat = tmp_stat
      msg = tmp_msg
    end if
    call write_sidecar(this, stat, msg)

  contains

    !> /mesh/<name>: one integer per cell, in the cells' selection.
    subroutine write_cell_ints(g, name, v)
      integer(HID_T), intent(in) :: g
      character(len=*), intent(in) :: name
      integer(i8), intent(in) :: v(:)
      integer(HID_T) :: fs, ms, d
      integer :: e
      fs = -1
      ms = -1
      d = -1
      one: block
        call h5screate_simple_f(1, [int(this%n_cells, HSIZE_T)], fs, e)
        if (failed(this%path, e, 'h5screate_simple_f', '/mesh/'//name, stat, msg)) exit one
        call select_runs(this%path, fs, '/mesh/'//name, 0, cstart, clen, stat, msg)
        call make_mem_space(this%path, 0, n_my_cells, '/mesh/'//name, ms, stat, msg)
        if (stat /= 0) exit one
        call h5dcreate_f(g, name, H5T_STD_I64LE, fs, d, e, this%dcpl_id)
        if (failed(this%path, e, 'h5dcreate_f', '/mesh/'//name, stat, msg)) exit one
        call h5dwrite_f(d, this%int_mtype, v, shape(v, HSIZE_T), e, ms, fs, this%xfer_id)
        if (failed(this%path, e, 'h5dwrite_f', '/mesh/'//name, stat, msg)) exit one
      end block one
      if (d >= 0) call h5dclose_f(d, e)
      call close_space(this%path, fs, tmp_stat, tmp_msg)
      call close_space(this%path, ms, tmp_stat, tmp_msg)
    end subroutine write_cell_ints
  end procedure h5_output_write_mesh

  !> Empty if the arguments of write_mesh are consistent on this rank, else what is wrong.
  function check_mesh_args(this, mass, cells, cell_gids, coords) result(err)
    class(h5_output_t), intent(in) :: this
    real(wp), intent(in) :: mass(:)
    integer(i8), intent(in) :: cells(:, :), cell_gids(:)
    real(wp), intent(in), optional :: coords(:, :)
    character(len=:), allocatable :: err
    integer :: n

    err = ''
    n = size(cell_gids)
    if (present(coords)) err = check_coords(this, coords)
    if (len(err) > 0) return
    if (size(mass, kind=i8) /= this%n_owned) then
      err = 'mass must be (n_owned)'
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

  !> Empty if coords is (2, n_owned) on this rank, else what is wrong.
  function check_coords(this, coords) result(err)
    class(h5_output_t), intent(in) :: this
    real(wp), intent(in) :: coords(:, :)
    character(len=:), allocatable :: err
    err = ''
    if (size(coords, 1) /= 2 .or. size(coords, 2, kind=i8) /= this%n_owned) &
      err = 'coords must be (2, n_owned)'
  end function check_coords

  !> /mesh/coordinates in the open group gid (each rank its owned nodes), collectively;
  !> marks them written.
  subroutine write_coordinates(this, gid, coords, stat, msg)
    class(h5_output_t), intent(inout) :: this
    integer(HID_T), intent(in) :: gid
    real(wp), intent(in) :: coords(:, :)
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer(HID_T) :: did
    integer :: ierr
    if (stat /= 0) return
    call h5dcreate_f(gid, 'coordinates', H5T_IEEE_F64LE, this%node_fspace, did, ierr, &
      this%dcpl_id)
    if (failed(this%path, ierr, 'h5dcreate_f', '/mesh/coordinates', stat, msg)) return
    call h5dwrite_f(did, this%real_mtype, coords, shape(coords, HSIZE_T), ierr, &
      this%node_mspace, this%node_fspace, this%xfer_id)
    if (failed(this%path, ierr, 'h5dwrite_f', '/mesh/coordinates', stat, msg)) continue
    call h5dclose_f(did, ierr)
    if (failed(this%path, ierr, 'h5dclose_f', '/mesh/coordinates', stat, msg)) return
    if (stat == 0) this%coords_written = .true.
  end subroutine write_coordinates

  !> Writes /mesh/coordinates ahead of write_mesh (documented at its interface).
  module procedure h5_output_write_mesh_coordinates
    character(len=:), allocatable :: local_msg
    integer(HID_T) :: gid
    integer :: ierr, bad, any_bad

    stat = 0
    msg = ''
    if (.not. this%is_open .or. this%mesh_written .or. this%coords_written) then
      stat = 1
      msg = 'iem_h5_output: write_mesh_coordinates on a file that is not open or whose '// &
        'coordinates are written ('//this%path//')'
      return
    end if
    local_msg = check_coords(this, coords)
    bad = merge(1, 0, len(local_msg) > 0)
    call MPI_Allreduce(bad, any_bad, 1, MPI_INTEGER, MPI_MAX, this%comm)
    if (any_bad /= 0) then
      stat = 1
      if (bad == 0) local_msg = 'invalid arguments on another rank'
      msg = 'iem_h5_output: write_mesh_coordinates: '//local_msg//' ('//this%path//')'
      return
    end if
    call h5gopen_f(this%file_id, 'mesh', gid, ierr)
    if (failed(this%path, ierr, 'h5gopen_f', '/mesh', stat, msg)) return
    call write_coordinates(this, gid, coords, stat, msg)
    call h5gclose_f(gid, ierr)
    if (failed(this%path, ierr, 'h5gclose_f', '/mesh', stat, msg)) return
  end procedure h5_output_write_mesh_coordinates

end submodule iem_h5_output_mesh

!> /frames: one group of node fields (displacement, velocity), cell fields and the list of
!> failed springs a frame, and the series /frames/time and /frames/step; the sidecar lists
!> what each frame holds.
submodule (iem_h5_output) iem_h5_output_frames
  use mpi_f08, only: MPI_Allgather, MPI_Gatherv, MPI_Allreduce, MPI_IN_PLACE, MPI_MAX, &
    MPI_INTEGER, MPI_INTEGER8
  use iem_kinds, only: mpi_wp
  use iem_sort, only: stable_sort_by
  use iem_strings, only: itoa
  use iem_xdmf, only: xdmf_frame_name, xdmf_field_bit, xdmf_xyz_suffix
  use hdf5, only: HSIZE_T, h5fflush_f, H5F_SCOPE_GLOBAL_F, h5gcreate_f, h5gopen_f, h5gclose_f, &
    h5dcreate_f, h5dwrite_f, h5dclose_f, h5screate_simple_f, h5scopy_f, h5sselect_none_f, &
    H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, H5T_STD_I64LE, H5T_STD_I32LE, H5T_NATIVE_INTEGER, &
    h5pcreate_f, h5pclose_f, H5P_DATASET_CREATE_F, &
    h5pset_fill_value_f, h5pset_virtual_f, h5sselect_hyperslab_f, H5S_SELECT_SET_F, h5sclose_f
  use iem_h5_primitives, only: failed, put_attr, prepare_append, select_runs, make_mem_space, &
    close_space, one
  use, intrinsic :: iso_c_binding, only: c_ptr, c_loc
  implicit none

  !> Nodes of a frame's field written at a time (a 512 kB buffer).
  integer(i8), parameter :: frame_slab = 32768

contains

  !> Adds the next frame group (u, v of the owned nodes) and appends to /frames/time, step.
  module procedure h5_output_write_frame
    ! u, v: (2, n_owned) in owned_gids order. Collective; rank 0 then rewrites the sidecar.
    character(len=:), allocatable :: name, where
    real(wp), allocatable :: grown(:)
    integer, allocatable :: grown_fields(:)
    integer(HID_T) :: gid, fspace, mspace
    integer :: ierr, ru, rv, n_slabs
    logical :: shapes_ok

    ru = 1
    if (present(u_row)) ru = u_row
    rv = 1
    if (present(v_row)) rv = v_row
    stat = 0
    msg = ''
    if (.not. this%is_open) then
      stat = 1
      msg = 'iem_h5_output: write_frame on a file that is not open'
      return
    end if
    ! A rank with wrong shapes writes nothing but still takes part in every collective call,
    ! so that the other ranks do not hang; it reports the error afterwards.
    shapes_ok = ru >= 1 .and. size(u, 1) >= ru + 1 .and. &
      size(u, 2, kind=i8) == this%n_owned .and. &
      rv >= 1 .and. size(v, 1) >= rv + 1 .and. size(v, 2, kind=i8) == this%n_owned
    name = xdmf_frame_name(this%n_frames)
    where = '/frames/'//name
    ! every rank writes each field in the same number of collective writes
    n_slabs = int((this%n_owned + frame_slab - 1)/frame_slab)
    call MPI_Allreduce(MPI_IN_PLACE, n_slabs, 1, MPI_INTEGER, MPI_MAX, this%comm)
    gid = -1
    fspace = -1
    mspace = -1
    work: block
      call h5gcreate_f(this%frames_id, name, gid, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', where, stat, msg)) exit work
      call put_attr(this%path, gid, where, 'time', stat, msg, rval=time)
      call put_attr(this%path, gid, where, 'step', stat, msg, lval=step)
      call write_node_field(this, gid, where//'/displacement', 'displacement', u, shapes_ok, &
        stat, msg, ru, n_slabs)
      call write_node_field(this, gid, where//'/velocity', 'velocity', v, shapes_ok, stat, msg, &
        rv, n_slabs)
      call write_xyz_view(this, gid, where, 'displacement', stat, msg)
      call write_xyz_view(this, gid, where, 'velocity', stat, msg)
      if (stat /= 0) exit work

      call prepare_append(this%path, this%rank, this%frames_time_id, '/frames/time', 0, &
        this%n_frames, 1_i8, &
        fspace, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dwrite_f(this%frames_time_id, this%real_mtype, [time], one, ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', '/frames/time', stat, msg)) exit work
      call close_space(this%path, fspace, stat, msg)
      call close_space(this%path, mspace, stat, msg)
      call prepare_append(this%path, this%rank, this%frames_step_id, '/frames/step', 0, &
        this%n_frames, 1_i8, &
        fspace, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dwrite_f(this%frames_step_id, this%int_mtype, [step], one, ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', '/frames/step', stat, msg)) exit work

      call h5gclose_f(gid, ierr)
      gid = -1
      if (failed(this%path, ierr, 'h5gclose_f', where, stat, msg)) exit work
      ! Keeps the file readable if the run is killed later.
      call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
      if (failed(this%path, ierr, 'h5fflush_f', '/', stat, msg)) exit work
    end block work
    if (gid >= 0) call h5gclose_f(gid, ierr)
    call close_space(this%path, fspace, stat, msg)
    call close_space(this%path, mspace, stat, msg)

    if (stat == 0) then
      this%n_frames = this%n_frames + 1
      if (this%rank == 0) then
        if (this%n_frames > size(this%frame_times, kind=i8)) then
          allocate (grown(2*size(this%frame_times)))
          grown(:size(this%frame_times)) = this%frame_times
          call move_alloc(grown, this%frame_times)
          allocate (grown_fields(size(this%frame_times)))
          grown_fields = 0
          grown_fields(:size(this%frame_fields)) = this%frame_fields
          call move_alloc(grown_fields, this%frame_fields)
        end if
        this%frame_times(this%n_frames) = time
        this%frame_fields(this%n_frames) = ior(xdmf_field_bit('displacement'), &
                                               xdmf_field_bit('velocity'))
      end if
    end if
    call write_sidecar(this, stat, msg)
    if (.not. shapes_ok .and. stat /= 1) then
      stat = 1
      msg = 'iem_h5_output: write_frame: u and v must have rows u_row:u_row+1 and v_row:'// &
        'v_row+1 and '//itoa(this%n_owned)//' columns, the owned nodes of this rank; nothing '// &
        'written from it to '//where//' in '//this%path
    end if
  end procedure h5_output_write_frame

  !> Creates the node dataset `name` (2, n_nodes) in group `gid` and writes this rank's nodes
  !> from rows row:row+1 of field(:, n_owned), in n_slabs collective writes (the same number
  !> on every rank) of up to frame_slab nodes, each copied into one small buffer: no copy of
  !> the whole field (a strided selection in memory costs HDF5 and MPI-IO more than a copy,
  !> measured); one slab uses the rank's node selection as it is. If not shapes_ok, writes
  !> nothing but takes part. No-op if stat /= 0.
  subroutine write_node_field(this, gid, where, name, field, shapes_ok, stat, msg, row, n_slabs)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: gid
    character(len=*), intent(in) :: where, name
    real(wp), intent(in) :: field(:, :)
    logical, intent(in) :: shapes_ok
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer, intent(in) :: row, n_slabs
    real(wp), allocatable :: buf(:, :)
    integer(i8), allocatable :: starts(:), lens(:)
    integer(HID_T) :: did, fspace, mspace
    integer(i8) :: i0, i1, n_mine
    integer :: ierr, k

    if (stat /= 0) return
    did = -1
    fspace = -1
    mspace = -1
    n_mine = 0
    if (shapes_ok) n_mine = this%n_owned
    allocate(buf(2, max(1_i8, min(frame_slab, n_mine))))
    buf = 0.0_wp
    work: block
      call h5dcreate_f(gid, name, H5T_IEEE_F64LE, this%node_fspace, did, ierr, this%dcpl_id)
      if (failed(this%path, ierr, 'h5dcreate_f', where, stat, msg)) exit work
      do k = 1, n_slabs
        ! this rank's owned nodes i0..i1 (none when i1 < i0)
        i0 = (k - 1)*frame_slab + 1
        i1 = min(k*frame_slab, n_mine)
        if (i1 >= i0) buf(:, 1:i1 - i0 + 1) = field(row:row + 1, i0:i1)
        if (n_slabs == 1 .and. shapes_ok) then
          call h5dwrite_f(did, this%real_mtype, buf, shape(buf, HSIZE_T), ierr, &
            this%node_mspace, this%node_fspace, this%xfer_id)
        else
          call h5scopy_f(this%node_fspace, fspace, ierr)
          if (failed(this%path, ierr, 'h5scopy_f', where, stat, msg)) exit work
          call slab_runs(this%run_start, this%run_len, i0, i1, starts, lens)
          call select_runs(this%path, fspace, where, 2, starts, lens, stat, msg)
          call make_mem_space(this%path, 2, max(0_i8, i1 - i0 + 1), where, mspace, stat, msg)
          if (stat /= 0) exit work
          call h5dwrite_f(did, this%real_mtype, buf, shape(buf, HSIZE_T), ierr, mspace, fspace, &
            this%xfer_id)
          call close_space(this%path, fspace, stat, msg)
          call close_space(this%path, mspace, stat, msg)
        end if
        if (failed(this%path, ierr, 'h5dwrite_f', where, stat, msg)) exit work
      end do
    end block work
    if (did >= 0) then
      call h5dclose_f(did, ierr)
      if (failed(this%path, ierr, 'h5dclose_f', where, stat, msg)) continue
    end if
    call close_space(this%path, fspace, stat, msg)
    call close_space(this%path, mspace, stat, msg)
  end subroutine write_node_field

  !> The runs (first global node, length) of the owned nodes i0..i1 (1-based, in order) of a
  !> rank whose owned nodes are the runs (run_start, run_len); none when i1 < i0.
  pure subroutine slab_runs(run_start, run_len, i0, i1, starts, lens)
    integer(i8), intent(in) :: run_start(:), run_len(:), i0, i1
    integer(i8), allocatable, intent(out) :: starts(:), lens(:)
    integer(i8) :: first, last, a, b
    integer :: r, n, k_runs
    do n = 0, 1
      if (n == 1) allocate(starts(k_runs), lens(k_runs))
      k_runs = 0
      first = 1
      do r = 1, size(run_start)
        last = first + run_len(r) - 1
        a = max(first, i0)
        b = min(last, i1)
        if (a <= b) then
          k_runs = k_runs + 1
          if (n == 1) then
            starts(k_runs) = run_start(r) + (a - first)
            lens(k_runs) = b - a + 1
          end if
        end if
        first = last + 1
      end do
    end do
  end subroutine slab_runs

  !> Adds <name>_xyz to group `gid` (path `where`): a virtual dataset (n_nodes, 3) whose first
  !> two columns are the node vector <name> (n_nodes, 2) of the same group and whose third is
  !> 0, so that ParaView reads a 3-component vector. It takes no room for data. Collective;
  !> no-op if stat /= 0.
  subroutine write_xyz_view(this, gid, where, name, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: gid
    character(len=*), intent(in) :: where, name
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    character(len=:), allocatable :: view
    integer(HID_T) :: dcpl, vspace, sspace, did
    integer :: ierr

    if (stat /= 0) return
    view = where//'/'//name//xdmf_xyz_suffix
    dcpl = -1
    vspace = -1
    sspace = -1
    did = -1
    work: block
      call h5screate_simple_f(2, [3_HSIZE_T, int(this%n_nodes, HSIZE_T)], vspace, ierr)
      if (failed(this%path, ierr, 'h5screate_simple_f', view, stat, msg)) exit work
      call h5sselect_hyperslab_f(vspace, H5S_SELECT_SET_F, [0_HSIZE_T, 0_HSIZE_T], &
        [2_HSIZE_T, int(this%n_nodes, HSIZE_T)], ierr)
      if (failed(this%path, ierr, 'h5sselect_hyperslab_f', view, stat, msg)) exit work
      call h5screate_simple_f(2, [2_HSIZE_T, int(this%n_nodes, HSIZE_T)], sspace, ierr)
      if (failed(this%path, ierr, 'h5screate_simple_f', view, stat, msg)) exit work
      call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, ierr)
      if (failed(this%path, ierr, 'h5pcreate_f', view, stat, msg)) exit work
      call h5pset_fill_value_f(dcpl, H5T_NATIVE_DOUBLE, 0.0_wp, ierr)
      if (failed(this%path, ierr, 'h5pset_fill_value_f', view, stat, msg)) exit work
      ! source '.': this file
      call h5pset_virtual_f(dcpl, vspace, '.', where//'/'//name, sspace, ierr)
      if (failed(this%path, ierr, 'h5pset_virtual_f', view, stat, msg)) exit work
      call h5dcreate_f(gid, name//xdmf_xyz_suffix, H5T_IEEE_F64LE, vspace, did, ierr, dcpl)
      if (failed(this%path, ierr, 'h5dcreate_f', view, stat, msg)) exit work
    end block work
    if (did >= 0) then
      call h5dclose_f(did, ierr)
      if (failed(this%path, ierr, 'h5dclose_f', view, stat, msg)) continue
    end if
    if (dcpl >= 0) call h5pclose_f(dcpl, ierr)
    if (vspace >= 0) call h5sclose_f(vspace, ierr)
    if (sspace >= 0) call h5sclose_f(sspace, ierr)
  end subroutine write_xyz_view

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_write_cell_field
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
      if (failed(this%path, ierr, 'h5gopen_f', '/frames/'//frame, stat, msg)) exit work
      call h5screate_simple_f(1, [int(this%n_cells, HSIZE_T)], fspace, ierr)
      if (failed(this%path, ierr, 'h5screate_simple_f', where, stat, msg)) exit work
      call select_runs(this%path, fspace, where, 0, this%cell_start, this%cell_len, stat, msg)
      call make_mem_space(this%path, 0, size(values, kind=i8), where, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dcreate_f(gid, name, H5T_IEEE_F64LE, fspace, did, ierr, this%dcpl_id)
      if (failed(this%path, ierr, 'h5dcreate_f', where, stat, msg)) exit work
      call h5dwrite_f(did, this%real_mtype, values, [size(values, kind=HSIZE_T)], ierr, &
        mspace, fspace, this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', where, stat, msg)) exit work
    end block work
    if (did >= 0) call h5dclose_f(did, ierr)
    if (gid >= 0) call h5gclose_f(gid, ierr)
    call close_space(this%path, fspace, stat, msg)
    call close_space(this%path, mspace, stat, msg)
    if (stat == 0) then
      ! readable before the sidecar names it
      call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
      if (failed(this%path, ierr, 'h5fflush_f', '/', stat, msg)) continue
    end if
    if (stat == 0 .and. this%rank == 0) this%frame_fields(this%n_frames) = &
      ior(this%frame_fields(this%n_frames), xdmf_field_bit(name))
    call write_sidecar(this, stat, msg)
  end procedure h5_output_write_cell_field

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_write_failed_springs
    ! Rank 0 gathers the entries as keys cell*8 + spring (unique, in (cell, spring) order),
    ! kinds and times, sorts them and writes them; the other ranks select nothing.
    integer, parameter :: springs = 8
    character(len=:), allocatable :: frame, where
    integer(i8), allocatable :: key(:), all_key(:)
    integer(i8), allocatable, target :: out_cell(:)
    integer, allocatable :: counts(:), displs(:), all_kind(:), order(:)
    integer, allocatable, target :: out_spring(:), out_kind(:)
    real(wp), allocatable :: all_time(:)
    real(wp), allocatable, target :: out_time(:)
    integer(HID_T) :: frame_id, gid
    integer :: n_mine, n, n_out, k, r, ierr
    logical :: shapes_ok

    stat = 0
    msg = ''
    if (.not. this%is_open .or. this%n_frames == 0) then
      stat = 1
      msg = 'iem_h5_output: write_failed_springs needs an open file and a frame'
      return
    end if
    frame = xdmf_frame_name(this%n_frames - 1)
    where = '/frames/'//frame//'/failed_springs'
    ! a rank with wrong shapes contributes nothing but takes part; it reports afterwards
    shapes_ok = size(spring) == size(cell) .and. size(kinds) == size(cell) .and. &
                size(time) == size(cell)
    n_mine = 0
    if (shapes_ok) n_mine = size(cell)
    allocate (counts(this%n_ranks), displs(this%n_ranks))
    call MPI_Allgather(n_mine, 1, MPI_INTEGER, counts, 1, MPI_INTEGER, this%comm)
    displs(1) = 0
    do r = 2, this%n_ranks
      displs(r) = displs(r - 1) + counts(r - 1)
    end do
    n = sum(counts)
    n_out = 0
    if (this%rank == 0) n_out = n
    allocate (key(max(n_mine, 1)), all_key(max(n_out, 1)), all_kind(max(n_out, 1)), &
              all_time(max(n_out, 1)))
    key = 0
    do k = 1, n_mine
      key(k) = int(springs, i8)*cell(k) + spring(k)
    end do
    all_key = 0
    all_kind = 0
    all_time = 0.0_wp
    call MPI_Gatherv(key, n_mine, MPI_INTEGER8, all_key, counts, displs, MPI_INTEGER8, 0, &
                     this%comm)
    call MPI_Gatherv(kinds, n_mine, MPI_INTEGER, all_kind, counts, displs, MPI_INTEGER, 0, &
                     this%comm)
    call MPI_Gatherv(time, n_mine, mpi_wp(), all_time, counts, displs, mpi_wp(), 0, this%comm)
    deallocate (key)
    allocate (order(max(n_out, 1)), out_cell(max(n_out, 1)), out_spring(max(n_out, 1)), &
              out_kind(max(n_out, 1)), out_time(max(n_out, 1)))
    out_cell = 0
    out_spring = 0
    out_kind = 0
    out_time = 0.0_wp
    if (n_out > 0) then
      ! by cell, then spring
      order(1:n_out) = [(k, k = 1, n_out)]
      call stable_sort_by(all_key(1:n_out), order(1:n_out))
      do k = 1, n_out
        out_cell(k) = all_key(order(k))/springs
        out_spring(k) = int(modulo(all_key(order(k)), int(springs, i8)))
        out_kind(k) = all_kind(order(k))
        out_time(k) = all_time(order(k))
      end do
    end if
    deallocate (all_key, all_kind, all_time, order)

    frame_id = -1
    gid = -1
    work: block
      call h5gopen_f(this%frames_id, frame, frame_id, ierr)
      if (failed(this%path, ierr, 'h5gopen_f', '/frames/'//frame, stat, msg)) exit work
      call h5gcreate_f(frame_id, 'failed_springs', gid, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', where, stat, msg)) exit work
      call write_list(this, gid, where, 'cell', H5T_STD_I64LE, this%int_mtype, n, n_out, &
                      c_loc(out_cell), stat, msg)
      call write_list(this, gid, where, 'spring', H5T_STD_I32LE, H5T_NATIVE_INTEGER, n, n_out, &
                      c_loc(out_spring), stat, msg)
      call write_list(this, gid, where, 'kind', H5T_STD_I32LE, H5T_NATIVE_INTEGER, n, n_out, &
                      c_loc(out_kind), stat, msg)
      call write_list(this, gid, where, 'time', H5T_IEEE_F64LE, this%real_mtype, n, n_out, &
                      c_loc(out_time), stat, msg)
    end block work
    if (gid >= 0) then
      call h5gclose_f(gid, ierr)
      if (failed(this%path, ierr, 'h5gclose_f', where, stat, msg)) continue
    end if
    if (frame_id >= 0) call h5gclose_f(frame_id, ierr)
    if (stat == 0) then
      call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
      if (failed(this%path, ierr, 'h5fflush_f', '/', stat, msg)) continue
    end if
    if (.not. shapes_ok .and. stat == 0) then
      stat = 1
      msg = 'iem_h5_output: write_failed_springs: cell, spring, kind and time differ in '// &
            'length; nothing written from this rank to '//where//' in '//this%path
    end if
  end procedure h5_output_write_failed_springs

  !> Creates the 1-D dataset `name` (file type ftype) of n entries in group `gid` and, when
  !> n > 0, writes the n_out entries at buf (memory type mtype; n_out is n on the writing
  !> rank, 0 on the others, which select nothing). Collective; no-op if stat /= 0.
  subroutine write_list(this, gid, where, name, ftype, mtype, n, n_out, buf, stat, msg)
    class(h5_output_t), intent(in) :: this
    integer(HID_T), intent(in) :: gid, ftype, mtype
    character(len=*), intent(in) :: where, name
    integer, intent(in) :: n, n_out
    type(c_ptr), intent(in) :: buf
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer(HID_T) :: did, fspace, mspace
    integer :: ierr

    if (stat /= 0) return
    did = -1
    fspace = -1
    mspace = -1
    work: block
      call h5screate_simple_f(1, [int(n, HSIZE_T)], fspace, ierr)
      if (failed(this%path, ierr, 'h5screate_simple_f', where//'/'//name, stat, msg)) exit work
      call h5dcreate_f(gid, name, ftype, fspace, did, ierr, this%dcpl_id)
      if (failed(this%path, ierr, 'h5dcreate_f', where//'/'//name, stat, msg)) exit work
      if (n == 0) exit work
      if (n_out == 0) then
        call h5sselect_none_f(fspace, ierr)
        if (failed(this%path, ierr, 'h5sselect_none_f', where//'/'//name, stat, msg)) exit work
      end if
      call make_mem_space(this%path, 0, int(n_out, i8), where//'/'//name, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dwrite_f(did, mtype, buf, ierr, mspace, fspace, this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', where//'/'//name, stat, msg)) exit work
    end block work
    if (did >= 0) then
      call h5dclose_f(did, ierr)
      if (failed(this%path, ierr, 'h5dclose_f', where//'/'//name, stat, msg)) continue
    end if
    call close_space(this%path, fspace, stat, msg)
    call close_space(this%path, mspace, stat, msg)
  end subroutine write_list


end submodule iem_h5_output_frames

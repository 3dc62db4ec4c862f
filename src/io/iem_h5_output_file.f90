!> The output file itself: create (header, groups, empty series), close, the HDF5
!> property lists, the ParaView sidecar, and releasing what is open after a failure.
submodule (iem_h5_output) iem_h5_output_file
  use iem_kinds, only: mpi_i8
  use iem_strings, only: itoa
  use iem_xdmf, only: xdmf_write, xdmf_path_of, xdmf_fields
  use iem_paths, only: mpiio_name
  use mpi_f08, only: MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, MPI_Bcast, MPI_INTEGER, &
    MPI_LOGICAL, MPI_MAX, MPI_SUM, MPI_INFO_NULL
  use hdf5, only: HSIZE_T, h5open_f, h5kind_to_type, H5_REAL_KIND, H5_INTEGER_KIND, h5pcreate_f, &
    h5pclose_f, h5pset_fapl_mpio_f, h5pset_libver_bounds_f, h5pset_all_coll_metadata_ops_f, &
    h5pset_coll_metadata_write_f, h5pset_dxpl_mpio_f, h5pset_fill_time_f, H5P_FILE_ACCESS_F, &
    H5P_DATASET_CREATE_F, H5P_DATASET_XFER_F, H5FD_MPIO_COLLECTIVE_F, H5D_FILL_TIME_NEVER_F, &
    H5F_LIBVER_V18_F, H5F_LIBVER_LATEST_F, h5fcreate_f, h5fclose_f, h5fflush_f, H5F_ACC_TRUNC_F, &
    H5F_ACC_EXCL_F, H5F_SCOPE_GLOBAL_F, h5gcreate_f, h5gclose_f, h5screate_simple_f, h5aopen_f, &
    h5awrite_f, h5aclose_f, H5T_NATIVE_INTEGER, H5T_STD_I64LE, H5T_IEEE_F64LE, h5lexists_f
  use iem_h5_layout, only: energy_names, static_names
  use iem_h5_primitives, only: failed, put_attr, create_series, select_runs, make_mem_space, &
    close_space, close_dset, gid_runs, one
  implicit none

contains

  !> Creates the output file collectively (stat /= 0 if it exists and overwrite is off).
  module procedure h5_output_create
    ! Writes the header attributes, creates the groups and the empty history datasets (with
    ! /history/static when analysis is 'static'), and builds this rank's node selection.
    ! owned_gids: this rank's nodes, 0-based, strictly ascending, a partition of
    ! 0..n_nodes-1 over the ranks. The strings and probe arguments
    ! must be the same on every rank. comm is kept (not duplicated) while the file is open.
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
    this%coords_written = .false.
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
    if (allocated(this%frame_fields)) deallocate (this%frame_fields)
    allocate (this%frame_times(16), this%frame_fields(16))
    this%frame_fields = 0
    this%mesh_fields = 0

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
      if (failed(this%path, ierr, 'h5fcreate_f', '/', stat, msg)) exit work
      this%is_open = .true.
      call dataset_lists(this, stat, msg)
      if (stat /= 0) exit work

      call put_attr(this%path, this%file_id, '/', 'program', stat, msg, text='iem')
      call put_attr(this%path, this%file_id, '/', 'file_type', stat, msg, text='iem_output')
      call put_attr(this%path, this%file_id, '/', 'version', stat, msg, text=version)
      call put_attr(this%path, this%file_id, '/', 'n_ranks', stat, msg, ival=this%n_ranks)
      call put_attr(this%path, this%file_id, '/', 'input_file', stat, msg, text=input_file)
      call put_attr(this%path, this%file_id, '/', 'input_text', stat, msg, text=input_text)
      call put_attr(this%path, this%file_id, '/', 'analysis', stat, msg, text=analysis)
      call put_attr(this%path, this%file_id, '/', 'units', stat, msg, text='SI: m, kg, s, N, Pa, J')
      call put_attr(this%path, this%file_id, '/', 'complete', stat, msg, ival=0)
      if (stat /= 0) exit work

      call h5gcreate_f(this%file_id, 'mesh', pgid, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', '/mesh', stat, msg)) exit work
      call h5gclose_f(pgid, ierr)
      pgid = -1
      if (failed(this%path, ierr, 'h5gclose_f', '/mesh', stat, msg)) exit work

      call h5gcreate_f(this%file_id, 'frames', this%frames_id, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', '/frames', stat, msg)) exit work
      call create_series(this%path, this%frames_id, '/frames/', 'time', H5T_IEEE_F64LE, 0, &
        this%frames_time_id, stat, msg)
      call create_series(this%path, this%frames_id, '/frames/', 'step', H5T_STD_I64LE, 0, &
        this%frames_step_id, stat, msg)
      if (stat /= 0) exit work

      call h5gcreate_f(this%file_id, 'history', hist_id, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', '/history', stat, msg)) exit work
      call create_series(this%path, hist_id, '/history/', 'time', H5T_IEEE_F64LE, 0, &
        this%hist_time_id, stat, msg)
      call create_series(this%path, hist_id, '/history/', 'step', H5T_STD_I64LE, 0, &
        this%hist_step_id, stat, msg)
      if (stat /= 0) exit work
      call h5gcreate_f(hist_id, 'energy', energy_gid, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', '/history/energy', stat, msg)) exit work
      do k = 1, n_energies
        call create_series(this%path, energy_gid, '/history/energy/', trim(energy_names(k)), &
          H5T_IEEE_F64LE, 0, this%energy_id(k), stat, msg)
      end do
      if (stat /= 0) exit work
      if (this%static) then
        call h5gcreate_f(hist_id, 'static', static_gid, ierr)
        if (failed(this%path, ierr, 'h5gcreate_f', '/history/static', stat, msg)) exit work
        call create_series(this%path, static_gid, '/history/static/', trim(static_names(1)), &
          H5T_IEEE_F64LE, 0, this%static_id(1), stat, msg)
        call create_series(this%path, static_gid, '/history/static/', trim(static_names(2)), &
          H5T_STD_I64LE, 0, this%static_id(2), stat, msg)
        call create_series(this%path, static_gid, '/history/static/', trim(static_names(3)), &
          H5T_IEEE_F64LE, 0, this%static_id(3), stat, msg)
        if (stat /= 0) exit work
      end if
      call h5gcreate_f(hist_id, 'probes', probes_gid, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', '/history/probes', stat, msg)) exit work
      do p = 1, size(probe_names)
        pname = trim(probe_names(p))
        call h5gcreate_f(probes_gid, pname, pgid, ierr)
        if (failed(this%path, ierr, 'h5gcreate_f', '/history/probes/'//pname, stat, msg)) exit work
        call put_attr(this%path, pgid, '/history/probes/'//pname, 'x', stat, msg, &
          rval=probe_xy(1, p))
        call put_attr(this%path, pgid, '/history/probes/'//pname, 'y', stat, msg, &
          rval=probe_xy(2, p))
        call put_attr(this%path, pgid, '/history/probes/'//pname, 'node', stat, msg, &
          lval=probe_node(p))
        call put_attr(this%path, pgid, '/history/probes/'//pname, 'node_x', stat, msg, &
          rval=probe_node_xy(1, p))
        call put_attr(this%path, pgid, '/history/probes/'//pname, 'node_y', stat, msg, &
          rval=probe_node_xy(2, p))
        call create_series(this%path, pgid, '/history/probes/'//pname//'/', 'displacement', &
          H5T_IEEE_F64LE, 2, this%probe_u_id(p), stat, msg)
        call create_series(this%path, pgid, '/history/probes/'//pname//'/', 'velocity', &
          H5T_IEEE_F64LE, 2, this%probe_v_id(p), stat, msg)
        if (stat /= 0) exit work
        call h5gclose_f(pgid, ierr)
        pgid = -1
        if (failed(this%path, ierr, 'h5gclose_f', '/history/probes/'//pname, stat, msg)) exit work
      end do

      ! The selection of this rank's nodes, built once and used by every frame.
      call select_owned_nodes(this, stat, msg)
    end block work

    ! Temporaries, closed on success and on failure alike; the first error is kept.
    tmp_stat = 0
    tmp_msg = ''
    if (pgid >= 0) call h5gclose_f(pgid, ierr)
    if (static_gid >= 0) then
      call h5gclose_f(static_gid, ierr)
      if (failed(this%path, ierr, 'h5gclose_f', '/history/static', tmp_stat, tmp_msg)) continue
    end if
    if (probes_gid >= 0) then
      call h5gclose_f(probes_gid, ierr)
      if (failed(this%path, ierr, 'h5gclose_f', '/history/probes', tmp_stat, tmp_msg)) continue
    end if
    if (energy_gid >= 0) then
      call h5gclose_f(energy_gid, ierr)
      if (failed(this%path, ierr, 'h5gclose_f', '/history/energy', tmp_stat, tmp_msg)) continue
    end if
    if (hist_id >= 0) then
      call h5gclose_f(hist_id, ierr)
      if (failed(this%path, ierr, 'h5gclose_f', '/history', tmp_stat, tmp_msg)) continue
    end if
    if (fapl >= 0) then
      call h5pclose_f(fapl, ierr)
      if (failed(this%path, ierr, 'h5pclose_f', 'file access list', tmp_stat, tmp_msg)) continue
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
  end procedure h5_output_create

  !> Closes the file collectively, after setting complete = 1 as the last write if `complete`.
  module procedure h5_output_close
    ! Rank 0 then rewrites the sidecar. Does nothing if the file is not open (never created,
    ! failed create, closed already).
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
        if (failed(this%path, ierr, 'h5fflush_f', '/', stat, msg)) exit work
        call h5aopen_f(this%file_id, 'complete', attr, ierr)
        if (failed(this%path, ierr, 'h5aopen_f', '/ attribute complete', stat, msg)) exit work
        one_value = 1
        call h5awrite_f(attr, H5T_NATIVE_INTEGER, one_value, one, ierr)
        if (failed(this%path, ierr, 'h5awrite_f', '/ attribute complete', stat, msg)) exit work
      end block work
      if (attr >= 0) then
        call h5aclose_f(attr, ierr)
        if (failed(this%path, ierr, 'h5aclose_f', '/ attribute complete', stat, msg)) continue
      end if
    end if
    call h5fclose_f(this%file_id, ierr)
    if (failed(this%path, ierr, 'h5fclose_f', '/', stat, msg)) continue
    this%file_id = -1
    this%is_open = .false.
    call write_sidecar(this, stat, msg)
  end procedure h5_output_close

  !> Documented at its interface in iem_h5_output.f90.
  module procedure file_access_list
    integer :: ierr
    if (.not. library_open) then
      call h5open_f(ierr)
      if (failed(this%path, ierr, 'h5open_f', 'the HDF5 library', stat, msg)) return
      library_open = .true.
    end if
    this%real_mtype = h5kind_to_type(wp, H5_REAL_KIND)
    this%int_mtype = h5kind_to_type(i8, H5_INTEGER_KIND)
    call h5pcreate_f(H5P_FILE_ACCESS_F, fapl, ierr)
    if (failed(this%path, ierr, 'h5pcreate_f', 'file access list', stat, msg)) return
    call h5pset_fapl_mpio_f(fapl, comm%MPI_VAL, MPI_INFO_NULL%MPI_VAL, ierr)
    if (failed(this%path, ierr, 'h5pset_fapl_mpio_f', 'file access list', stat, msg)) return
    ! 1.8 file format or later: compact/dense groups (many frames) and large attributes
    ! (input_text above 64 KiB); still readable by any HDF5 since 1.8.
    call h5pset_libver_bounds_f(fapl, H5F_LIBVER_V18_F, H5F_LIBVER_LATEST_F, ierr)
    if (failed(this%path, ierr, 'h5pset_libver_bounds_f', 'file access list', stat, msg)) return
    call h5pset_all_coll_metadata_ops_f(fapl, .true., ierr)
    if (failed(this%path, ierr, 'h5pset_all_coll_metadata_ops_f', 'file access list', stat, msg)) &
      return
    call h5pset_coll_metadata_write_f(fapl, .true., ierr)
    if (failed(this%path, ierr, 'h5pset_coll_metadata_write_f', 'file access list', stat, msg)) &
      return
  end procedure file_access_list

  !> Documented at its interface in iem_h5_output.f90.
  module procedure dataset_lists
    integer :: ierr
    call h5pcreate_f(H5P_DATASET_XFER_F, this%xfer_id, ierr)
    if (failed(this%path, ierr, 'h5pcreate_f', 'transfer list', stat, msg)) return
    call h5pset_dxpl_mpio_f(this%xfer_id, H5FD_MPIO_COLLECTIVE_F, ierr)
    if (failed(this%path, ierr, 'h5pset_dxpl_mpio_f', 'transfer list', stat, msg)) return
    call h5pcreate_f(H5P_DATASET_CREATE_F, this%dcpl_id, ierr)
    if (failed(this%path, ierr, 'h5pcreate_f', 'dataset creation list', stat, msg)) return
    call h5pset_fill_time_f(this%dcpl_id, H5D_FILL_TIME_NEVER_F, ierr)
    if (failed(this%path, ierr, 'h5pset_fill_time_f', 'dataset creation list', stat, msg)) return
  end procedure dataset_lists

  !> Documented at its interface in iem_h5_output.f90.
  module procedure write_sidecar
    character(len=:), allocatable :: xmsg
    integer :: xstat, k, ierr
    logical :: exists

    ! The /mesh fields of the table that the file holds now (a closed file keeps the last
    ! answer). Every rank asks: metadata reads are collective.
    if (this%is_open) then
      call h5lexists_f(this%file_id, 'mesh', exists, ierr)
      if (ierr == 0 .and. exists) then
        do k = 1, size(xdmf_fields)
          if (xdmf_fields(k)%per_frame .or. btest(this%mesh_fields, k - 1)) cycle
          call h5lexists_f(this%file_id, 'mesh/'//trim(xdmf_fields(k)%name), exists, ierr)
          if (ierr == 0 .and. exists) this%mesh_fields = ibset(this%mesh_fields, k - 1)
        end do
      end if
    end if
    xstat = 0
    if (this%rank == 0 .and. stat == 0) then
      call xdmf_write(this%xmf_path, this%h5_name, this%n_nodes, this%n_cells, &
        this%frame_times(:this%n_frames), this%frame_fields(:this%n_frames), this%mesh_fields, &
        xstat, xmsg)
    end if
    call MPI_Bcast(xstat, 1, MPI_INTEGER, 0, this%comm)
    if (xstat == 0 .or. stat /= 0) return
    stat = h5_output_sidecar_error
    if (this%rank == 0) then
      msg = xmsg
    else
      msg = 'iem_h5_output: rank 0 could not write the sidecar '//this%xmf_path
    end if
  end procedure write_sidecar

  !> Closes every open object of the file except the file itself; keeps the first error.
  subroutine release_objects(this, stat, msg)
    class(h5_output_t), intent(inout) :: this
    integer, intent(inout) :: stat
    character(len=:), allocatable, intent(inout) :: msg
    integer :: ierr, k

    call close_dset(this%path, this%frames_time_id, '/frames/time', stat, msg)
    call close_dset(this%path, this%frames_step_id, '/frames/step', stat, msg)
    call close_dset(this%path, this%hist_time_id, '/history/time', stat, msg)
    call close_dset(this%path, this%hist_step_id, '/history/step', stat, msg)
    do k = 1, n_energies
      call close_dset(this%path, this%energy_id(k), '/history/energy/'//trim(energy_names(k)), &
        stat, msg)
    end do
    do k = 1, n_static
      call close_dset(this%path, this%static_id(k), '/history/static/'//trim(static_names(k)), &
        stat, msg)
    end do
    if (allocated(this%probe_u_id)) then
      do k = 1, size(this%probe_u_id)
        call close_dset(this%path, this%probe_u_id(k), trim(this%probe_path(k))//'/displacement', &
          stat, msg)
        call close_dset(this%path, this%probe_v_id(k), trim(this%probe_path(k))//'/velocity', &
          stat, &
          msg)
      end do
    end if
    if (allocated(this%spring_e_id)) then
      do k = 1, size(this%spring_e_id)
        call close_dset(this%path, this%spring_e_id(k), trim(this%spring_path(k))//'/strain', &
          stat, &
          msg)
        call close_dset(this%path, this%spring_s_id(k), trim(this%spring_path(k))//'/stress', &
          stat, &
          msg)
      end do
      deallocate(this%spring_e_id, this%spring_s_id)
    end if
    if (allocated(this%reaction_id)) then
      do k = 1, size(this%reaction_id)
        call close_dset(this%path, this%reaction_id(k), trim(this%reaction_path(k)), stat, msg)
      end do
      deallocate(this%reaction_id)
    end if
    do k = 1, n_event_series
      call close_dset(this%path, this%event_id(k), '/history/fracture/events', stat, msg)
    end do
    call close_dset(this%path, this%fragments_id, '/history/fracture/fragments', stat, msg)
    call close_dset(this%path, this%largest_id, '/history/fracture/largest_fragments', stat, &
      msg)
    this%fracture = .false.
    if (this%frames_id >= 0) then
      call h5gclose_f(this%frames_id, ierr)
      this%frames_id = -1
      if (failed(this%path, ierr, 'h5gclose_f', '/frames', stat, msg)) continue
    end if
    call close_space(this%path, this%node_fspace, stat, msg)
    call close_space(this%path, this%node_mspace, stat, msg)
    if (this%xfer_id >= 0) then
      call h5pclose_f(this%xfer_id, ierr)
      this%xfer_id = -1
      if (failed(this%path, ierr, 'h5pclose_f', 'transfer list', stat, msg)) continue
    end if
    if (this%dcpl_id >= 0) then
      call h5pclose_f(this%dcpl_id, ierr)
      this%dcpl_id = -1
      if (failed(this%path, ierr, 'h5pclose_f', 'dataset creation list', stat, msg)) continue
    end if
  end subroutine release_objects

  !> Closes every open object and the file, after a failure; keeps the first error.
  module procedure release
    integer :: ierr

    call release_objects(this, stat, msg)
    if (this%file_id >= 0) then
      call h5fclose_f(this%file_id, ierr)
      this%file_id = -1
      if (failed(this%path, ierr, 'h5fclose_f', '/', stat, msg)) continue
    end if
    this%is_open = .false.
  end procedure release

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

end submodule iem_h5_output_file

!> Continued runs: reopening the output of an interrupted run to append to it
!> (cut back to what its checkpoint covers) and /continuations.
submodule (iem_h5_output) iem_h5_output_reopen
  use iem_strings, only: itoa
  use iem_xdmf, only: xdmf_frame_name, xdmf_path_of, xdmf_fields
  use iem_paths, only: mpiio_name
  use mpi_f08, only: MPI_Comm_rank, MPI_Comm_size, MPI_Bcast, MPI_CHARACTER
  use hdf5, only: HSIZE_T, h5pclose_f, h5fflush_f, H5F_SCOPE_GLOBAL_F, h5fopen_f, &
    H5F_ACC_RDWR_F, h5lexists_f, h5ldelete_f, h5dopen_f, h5dread_f, h5sget_simple_extent_dims_f, &
    h5gcreate_f, h5gopen_f, h5gclose_f, h5gget_info_f, h5dset_extent_f, h5dget_space_f, &
    h5screate_simple_f, h5sclose_f, h5aopen_f, h5awrite_f, h5aclose_f, H5T_NATIVE_INTEGER
  use iem_h5_layout, only: energy_names
  use iem_h5_primitives, only: failed, put_attr, select_runs, make_mem_space, gid_runs, one, &
    close_space, open_cut
  implicit none

contains

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_reopen
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
      if (failed(this%path, ierr, 'h5fopen_f', '/', stat, msg)) exit work
      this%is_open = .true.
      call dataset_lists(this, stat, msg)
      if (stat /= 0) exit work
      ! incomplete again until this run ends normally
      call h5aopen_f(this%file_id, 'complete', attr, ierr)
      if (failed(this%path, ierr, 'h5aopen_f', '/ attribute complete', stat, msg)) exit work
      zero = 0
      call h5awrite_f(attr, H5T_NATIVE_INTEGER, zero, one, ierr)
      if (failed(this%path, ierr, 'h5awrite_f', '/ attribute complete', stat, msg)) exit work

      ! the series, cut back to what the checkpoint covers
      call h5gopen_f(this%file_id, 'frames', this%frames_id, ierr)
      if (failed(this%path, ierr, 'h5gopen_f', '/frames', stat, msg)) exit work
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
        if (failed(this%path, ierr, 'h5lexists_f', '/frames/'//frame, stat, msg)) exit work
        if (.not. exists) exit
        call h5ldelete_f(this%frames_id, frame, ierr)
        if (failed(this%path, ierr, 'h5ldelete_f', '/frames/'//frame, stat, msg)) exit work
        have = have + 1
      end do
      this%n_frames = n_frames
      ! frame times for the sidecar
      if (allocated(this%frame_times)) deallocate (this%frame_times)
      allocate (this%frame_times(max(16_i8, 2*n_frames)))
      if (n_frames > 0) then
        call h5dread_f(this%frames_time_id, this%real_mtype, this%frame_times(1:n_frames), &
          [int(n_frames, HSIZE_T)], ierr)
        if (failed(this%path, ierr, 'h5dread_f', '/frames/time', stat, msg)) exit work
      end if
      ! and the fields each kept frame holds
      if (allocated(this%frame_fields)) deallocate (this%frame_fields)
      allocate (this%frame_fields(size(this%frame_times)))
      this%frame_fields = 0
      this%mesh_fields = 0
      do have = 1, n_frames
        frame = xdmf_frame_name(have - 1)
        do k = 1, size(xdmf_fields)
          if (.not. xdmf_fields(k)%per_frame) cycle
          call h5lexists_f(this%frames_id, frame//'/'//trim(xdmf_fields(k)%name), exists, ierr)
          if (failed(this%path, ierr, 'h5lexists_f', '/frames/'//frame, stat, msg)) exit work
          if (exists) this%frame_fields(have) = ibset(this%frame_fields(have), k - 1)
        end do
      end do

      call select_owned_nodes(this, stat, msg)
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
      dset = -1
      call open_cut(loc, this%path, name, where, ncomp, n, dset, stat, msg)
    end subroutine open_series
  end procedure h5_output_reopen

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_record_continuation
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
      if (failed(this%path, ierr, 'h5lexists_f', '/continuations', stat, msg)) exit work
      if (exists) then
        call h5gopen_f(this%file_id, 'continuations', grp, ierr)
        if (failed(this%path, ierr, 'h5gopen_f', '/continuations', stat, msg)) exit work
      else
        call h5gcreate_f(this%file_id, 'continuations', grp, ierr)
        if (failed(this%path, ierr, 'h5gcreate_f', '/continuations', stat, msg)) exit work
      end if
      call h5gget_info_f(grp, storage, n_links, max_corder, ierr)
      if (failed(this%path, ierr, 'h5gget_info_f', '/continuations', stat, msg)) exit work
      write(name, '(i4.4)') n_links + 1
      where = '/continuations/'//name
      call h5gcreate_f(grp, name, sub, ierr)
      if (failed(this%path, ierr, 'h5gcreate_f', where, stat, msg)) exit work
      call put_attr(this%path, sub, where, 'checkpoint', stat, msg, text=checkpoint)
      call put_attr(this%path, sub, where, 'time', stat, msg, rval=time)
      call put_attr(this%path, sub, where, 'step', stat, msg, lval=step)
      call put_attr(this%path, sub, where, 'n_ranks', stat, msg, ival=this%n_ranks)
      call put_attr(this%path, sub, where, 'date', stat, msg, text=trim(date))
      call put_attr(this%path, sub, where, 'samples', stat, msg, lval=this%n_samples)
      call put_attr(this%path, sub, where, 'frames', stat, msg, lval=this%n_frames)
    end block work
    if (sub >= 0) then
      call h5gclose_f(sub, ierr)
      if (failed(this%path, ierr, 'h5gclose_f', where, stat, msg)) continue
    end if
    if (grp >= 0) then
      call h5gclose_f(grp, ierr)
      if (failed(this%path, ierr, 'h5gclose_f', '/continuations', stat, msg)) continue
    end if
    if (stat /= 0) return
    call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
    if (failed(this%path, ierr, 'h5fflush_f', '/', stat, msg)) return
  end procedure h5_output_record_continuation

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_set_owned
    stat = 0
    msg = ''
    this%n_owned = size(owned_gids, kind=i8)
    call gid_runs(owned_gids, this%run_start, this%run_len)
    call gid_runs(cell_gids, this%cell_start, this%cell_len)
    call select_owned_nodes(this, stat, msg)
  end procedure h5_output_set_owned

  !> Documented at its interface in iem_h5_output.f90.
  module procedure select_owned_nodes
    integer :: ierr
    if (stat /= 0) return
    call close_space(this%path, this%node_fspace, stat, msg)
    call close_space(this%path, this%node_mspace, stat, msg)
    if (stat /= 0) return
    call h5screate_simple_f(2, [2_HSIZE_T, int(this%n_nodes, HSIZE_T)], this%node_fspace, ierr)
    if (failed(this%path, ierr, 'h5screate_simple_f', 'node file space', stat, msg)) return
    call select_runs(this%path, this%node_fspace, 'node file space', 2, this%run_start, &
      this%run_len, stat, msg)
    call make_mem_space(this%path, 2, this%n_owned, 'node memory space', this%node_mspace, &
      stat, msg)
  end procedure select_owned_nodes

end submodule iem_h5_output_reopen

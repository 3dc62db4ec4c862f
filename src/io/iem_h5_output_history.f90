!> /history: time, step, energies and probe series, the static series and settings
!> of a static run (/history/static), and the spring probes (/history/springs).
submodule (iem_h5_output) iem_h5_output_history
  use hdf5, only: HSIZE_T, h5fflush_f, H5F_SCOPE_GLOBAL_F, h5gcreate_f, h5gopen_f, h5gclose_f, &
    h5dwrite_f, H5T_IEEE_F64LE
  use iem_h5_layout, only: energy_names, static_names
  use iem_h5_primitives, only: failed, put_attr, create_series, prepare_append, close_space
  implicit none

contains

  !> Appends n samples to /history collectively; every rank passes the same data.
  module procedure h5_output_write_history
    ! time(n), step(n), energies(5, n) (kinetic, strain, external_work, damping,
    ! balance_error), probe_u and probe_v (2, n_probes, n). A static run's file (analysis =
    ! 'static') also takes load_factor(n), iterations(n), residual(n) for /history/static,
    ! and only it. Rank 0 selects the data, the others select nothing, all take part in the
    ! extend and the write.
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
      call prepare_append(this%path, this%rank, this%hist_time_id, '/history/time', 0, &
        this%n_samples, nn, &
        fspace, mspace, stat, msg)
      if (stat /= 0) exit work
      buf1 = time(:n)
      call h5dwrite_f(this%hist_time_id, this%real_mtype, buf1, dims1, ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', '/history/time', stat, msg)) exit work
      call close_space(this%path, fspace, stat, msg)
      call close_space(this%path, mspace, stat, msg)

      call prepare_append(this%path, this%rank, this%hist_step_id, '/history/step', 0, &
        this%n_samples, nn, &
        fspace, mspace, stat, msg)
      if (stat /= 0) exit work
      call h5dwrite_f(this%hist_step_id, this%int_mtype, step(:n), dims1, ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', '/history/step', stat, msg)) exit work
      call close_space(this%path, fspace, stat, msg)
      call close_space(this%path, mspace, stat, msg)

      do k = 1, n_energies
        call prepare_append(this%path, this%rank, this%energy_id(k), &
          '/history/energy/'//trim(energy_names(k)), &
          0, this%n_samples, nn, fspace, mspace, stat, msg)
        if (stat /= 0) exit work
        buf1 = energies(k, :n)
        call h5dwrite_f(this%energy_id(k), this%real_mtype, buf1, dims1, ierr, mspace, fspace, &
          this%xfer_id)
        if (failed(this%path, ierr, 'h5dwrite_f', '/history/energy/'//trim(energy_names(k)), stat, &
          msg)) exit work
        call close_space(this%path, fspace, stat, msg)
        call close_space(this%path, mspace, stat, msg)
      end do

      do p = 1, n_probes
        call prepare_append(this%path, this%rank, this%probe_u_id(p), trim(this%probe_path(p))// &
          '/displacement', 2, this%n_samples, nn, fspace, mspace, stat, msg)
        if (stat /= 0) exit work
        buf2 = probe_u(:, p, :n)
        call h5dwrite_f(this%probe_u_id(p), this%real_mtype, buf2, dims2, ierr, mspace, fspace, &
          this%xfer_id)
        if (failed(this%path, ierr, 'h5dwrite_f', trim(this%probe_path(p))//'/displacement', stat, &
          msg)) exit work
        call close_space(this%path, fspace, stat, msg)
        call close_space(this%path, mspace, stat, msg)

        call prepare_append(this%path, this%rank, this%probe_v_id(p), &
          trim(this%probe_path(p))//'/velocity', &
          2, this%n_samples, nn, fspace, mspace, stat, msg)
        if (stat /= 0) exit work
        buf2 = probe_v(:, p, :n)
        call h5dwrite_f(this%probe_v_id(p), this%real_mtype, buf2, dims2, ierr, mspace, fspace, &
          this%xfer_id)
        if (failed(this%path, ierr, 'h5dwrite_f', trim(this%probe_path(p))//'/velocity', stat, &
          msg)) exit work
        call close_space(this%path, fspace, stat, msg)
        call close_space(this%path, mspace, stat, msg)
      end do

      if (this%static) then
        do k = 1, n_static
          call prepare_append(this%path, this%rank, this%static_id(k), '/history/static/'// &
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
          if (failed(this%path, ierr, 'h5dwrite_f', '/history/static/'//trim(static_names(k)), &
            stat, msg)) exit work
          call close_space(this%path, fspace, stat, msg)
          call close_space(this%path, mspace, stat, msg)
        end do
      end if
      call h5fflush_f(this%file_id, H5F_SCOPE_GLOBAL_F, ierr)
      if (failed(this%path, ierr, 'h5fflush_f', '/', stat, msg)) exit work
    end block work
    call close_space(this%path, fspace, stat, msg)
    call close_space(this%path, mspace, stat, msg)
    if (stat == 0) this%n_samples = this%n_samples + nn
  end procedure h5_output_write_history

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_write_static_settings
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
    if (failed(this%path, ierr, 'h5gopen_f', where, stat, msg)) return
    call put_attr(this%path, gid, where, 'load_steps', stat, msg, ival=load_steps)
    call put_attr(this%path, gid, where, 'tolerance', stat, msg, rval=tolerance)
    call put_attr(this%path, gid, where, 'max_iterations', stat, msg, ival=max_iterations)
    call put_attr(this%path, gid, where, 'method', stat, msg, text=method)
    call put_attr(this%path, gid, where, 'mass', stat, msg, text=mass)
    call put_attr(this%path, gid, where, 'check_interval', stat, msg, ival=check_interval)
    call h5gclose_f(gid, ierr)
    if (failed(this%path, ierr, 'h5gclose_f', where, stat, msg)) return
  end procedure h5_output_write_static_settings

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_define_spring_probes
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
      if (failed(this%path, ierr, 'h5gcreate_f', '/history/springs', stat, msg)) exit work
      call put_attr(this%path, gid, '/history/springs', 'springs', stat, msg, text=labels)
      call put_attr(this%path, gid, '/history/springs', 'stress_definition', stat, msg, &
        text='spring modulus (Eq, Hq, Gq) times the normalised spring stress; strain: '// &
        'edge strain, sum of the two edge strains at the corner, corner shear measure')
      do p = 1, size(names)
        this%spring_path(p) = '/history/springs/'//trim(names(p))
        where = trim(this%spring_path(p))
        call h5gcreate_f(gid, trim(names(p)), pgid, ierr)
        if (failed(this%path, ierr, 'h5gcreate_f', where, stat, msg)) exit work
        call put_attr(this%path, pgid, where, 'cell', stat, msg, lval=cell_gids(p))
        call put_attr(this%path, pgid, where, 'x', stat, msg, rval=xy(1, p))
        call put_attr(this%path, pgid, where, 'y', stat, msg, rval=xy(2, p))
        call create_series(this%path, pgid, where//'/', 'strain', H5T_IEEE_F64LE, 12, &
          this%spring_e_id(p), stat, msg)
        call create_series(this%path, pgid, where//'/', 'stress', H5T_IEEE_F64LE, 12, &
          this%spring_s_id(p), stat, msg)
        if (stat /= 0) exit work
        call h5gclose_f(pgid, ierr)
        pgid = -1
        if (failed(this%path, ierr, 'h5gclose_f', where, stat, msg)) exit work
      end do
    end block work
    if (pgid >= 0) call h5gclose_f(pgid, ierr)
    if (gid >= 0) call h5gclose_f(gid, ierr)
  end procedure h5_output_define_spring_probes

  !> Documented at its interface in iem_h5_output.f90.
  module procedure h5_output_write_spring_history
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
  end procedure h5_output_write_spring_history

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
    call prepare_append(this%path, this%rank, dset, where, size(data, 1), old, size(data, 2, &
      kind=i8), fspace, &
      mspace, stat, msg)
    if (stat == 0) then
      call h5dwrite_f(dset, this%real_mtype, buf, shape(buf, HSIZE_T), ierr, mspace, fspace, &
        this%xfer_id)
      if (failed(this%path, ierr, 'h5dwrite_f', where, stat, msg)) continue
    end if
    call close_space(this%path, fspace, stat, msg)
    call close_space(this%path, mspace, stat, msg)
  end subroutine append_block

end submodule iem_h5_output_history

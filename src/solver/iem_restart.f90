!> Checkpoints and continued runs of a dynamic run (docs/output.md, "Exit status, checkpoints
!> and continued runs"): the checks of a checkpoint before a restart writes anything, writing
!> and loading checkpoints, the model's hash, and reopening the output to append to it.
submodule (iem_simulation) iem_restart
  use mpi_f08, only: MPI_Bcast, MPI_SUM, MPI_INTEGER8
  use iem_kinds, only: mpi_wp
  use iem_checkpoint, only: checkpoint_write, checkpoint_read_header, checkpoint_verify, &
                            checkpoint_read, checkpoint_check_layout, energy_words
  use iem_word_hash, only: text_hash
  use iem_h5_inspect, only: h5_output_inspect
  use iem_exact_sum, only: exact_sum_t, exact_sum_allreduce, exact_sum_packed_size
  implicit none

contains

  !> Check, before anything is written, that the checkpoint to continue from is whole and belongs to
  !> this run: its header, exact size and checksum (every byte), this model, grid and time step, the
  !> record layout of this run's checkpointed fields, and that output_file is the output it was
  !> written with and holds what it covers. Refused (stat /= 0, msg naming &run restart and what is
  !> wrong) otherwise; nothing is opened for writing. Collective.
  module procedure check_restart
    character(len=:), allocatable :: what, path, why, out
    integer(i8) :: have(2)
    real(wp) :: tail(8)
    type(field_registry_t), target :: reg
    path = trim(this%cfg%run%restart)
    out = trim(this%cfg%run%output_file)
    call checkpoint_read_header(path, this%comm, this%restart, stat, why)
    if (stat == 0) call checkpoint_verify(path, this%comm, this%restart, stat, why)
    if (stat /= 0) then
      msg = trim(this%cfg%input_file)//": &run: restart = '"//path//"' "//why
      return
    end if
    what = ''
    if (this%restart%nx /= this%grid%nx .or. this%restart%ny /= this%grid%ny) then
      what = 'a '//itoa(this%restart%nx)//' x '//itoa(this%restart%ny)//' grid'
    else if (this%restart%model_hash /= model_hash(this)) then
      what = 'a different model (geometry, material, damping, conditions, loads, initial '// &
             'state, integrator or time step differ)'
    else if (this%restart%step > this%n_steps) then
      what = 'step '//itoa(this%restart%step)//', beyond the '//itoa(this%n_steps)// &
             ' steps of this run'
    end if
    if (len(what) > 0) then
      stat = 1
      msg = trim(this%cfg%input_file)//": &run: restart = '"//path//"' was written for "// &
            what//'; it can only continue the run that wrote it'
      return
    end if
    ! the records: this run's checkpointed fields (the registration alone, no values)
    call state_layout(this, reg, .true., stat)
    if (stat == 0) call checkpoint_check_layout(this%restart, reg, stat, why)
    call reg%free()
    if (stat /= 0) then
      msg = trim(this%cfg%input_file)//": &run: restart = '"//path//"' "//why
      return
    end if
    ! the output: rank 0 looks at it (read-only) and all agree
    have = 0
    tail = 0.0_wp
    if (this%rank == 0) call h5_output_inspect(out, this%restart%n_frames, &
      this%restart%n_samples, have(1), have(2), tail(1), tail(2:8), stat, why)
    call MPI_Bcast(stat, 1, MPI_INTEGER, 0, this%comm)
    call MPI_Bcast(have, 2, MPI_INTEGER8, 0, this%comm)
    call MPI_Bcast(tail, 8, mpi_wp(), 0, this%comm)
    what = ''
    if (stat /= 0) then
      what = "output_file = '"//out//"' "//why
    else if (have(1) < this%restart%n_frames .or. have(2) < this%restart%n_samples) then
      what = 'its time '//rtoa(this%restart%t)//" s is beyond the end of output_file = '"// &
             out//"' ("//itoa(have(1))//' frames and '//itoa(have(2))//' history samples; '// &
             'the checkpoint needs '//itoa(this%restart%n_frames)//' and '// &
             itoa(this%restart%n_samples)//')'
    else if (tail(1) /= this%restart%last_frame_time .or. &
             any(tail(2:8) /= this%restart%last_sample)) then
      what = "output_file = '"//out//"' is not the output it was written with (its frame "// &
             itoa(this%restart%n_frames)//' or history sample '// &
             itoa(this%restart%n_samples)//" differs from the checkpoint's record of them)"
    end if
    if (len(what) > 0) then
      stat = 1
      msg = trim(this%cfg%input_file)//": &run: restart = '"//path//"': "//what
      return
    end if
    stat = 0
    msg = ''
    if (this%restart%step == 0) this%restart%step = -1
  end procedure check_restart

  !> Write a checkpoint of the state at the top of step k (before its rates): the registry
  !> of the run's checkpointed fields (state_to_registry), its record of every owned node and
  !> every counted cell, the run's counters, the signal the run stops on (0: none).
  !> Collective.
  module procedure write_checkpoint
    type(checkpoint_header_t) :: h
    type(field_registry_t), target :: reg
    type(exact_sum_t) :: acc(3)
    integer(i8) :: packed(exact_sum_packed_size, 2)
    real(wp) :: slot(energy_words)
    integer :: worst
    call flush_history(this, stat)
    if (stat /= 0) then
      msg = 'writing the history before a checkpoint failed'
      return
    end if
    h%nx = this%grid%nx
    h%ny = this%grid%ny
    h%n_state = this%model%n_state
    h%nonlinear = merge(1_i8, 0_i8, this%model%nonlinear)
    h%depth = this%cfg%materials(1)%history_depth
    if (this%model%nonlinear) h%depth = this%model%nl%state%depth
    h%verlet = merge(1_i8, 0_i8, this%verlet)
    h%step = k
    h%n_samples = this%out%samples_written()
    h%n_frames = this%out%frames_written()
    h%n_ranks = this%n_ranks
    h%model_hash = model_hash(this)
    h%warned = merge(1_i8, 0_i8, this%warned)
    h%n_nodes = this%body%n_nodes
    h%n_cells = this%body%n_cells
    h%t = t
    h%dt = this%dt
    h%e0 = this%e0
    h%e_scale = this%e_scale
    h%last_balance = this%last_balance
    ! the header records the global work rounded (for people); the exact state of each rank's
    ! accumulators goes in its slot
    acc = [this%model%w_ext_acc, this%model%damping_work(this%lat), &
           this%model%kick_term(this%lat, this%st%acc, this%integ%kick_half(this%dt))]
    call exact_sum_allreduce(acc, this%comm)
    h%w_ext = acc(1)%value()
    h%w_damp = acc(2)%value()
    ! (for the sample at this step of a run continued from here)
    h%kick = acc(3)%value()
    call this%model%w_ext_acc%pack(packed(:, 1))
    call this%model%w_damp_acc%pack(packed(:, 2))
    slot = real(reshape(packed, [energy_words]), wp)
    h%stop_signal = sig
    h%last_sample = this%last_sample
    h%last_frame_time = this%last_frame_time
    ! the registry comes and goes with the checkpoint, the records packed from the run's own
    ! arrays (borrowed); out of memory (the records' buffer, a field it copies) ends the run
    ! cleanly
    call state_to_registry(this, reg, .true., stat, borrow=.true.)
    call MPI_Allreduce(stat, worst, 1, MPI_INTEGER, MPI_MAX, this%comm)
    if (worst /= 0) then
      stat = 1
      msg = 'checkpoint: '//trim(this%cfg%run%checkpoint_file)//': out of memory for the '// &
            'registry of the fields'
      call reg%free()
      return
    end if
    ! owned nodes are the registry's first node entities; the counted cells, by global index
    call checkpoint_write(trim(this%cfg%run%checkpoint_file), this%comm, h, slot, reg, &
                          this%lat%node_runs%table(), this%lat%counted_runs(), stat, msg)
    call reg%free()
    if (stat /= 0) return
    ! the state a diverging run on more than one rank steps again from
    if (this%n_ranks > 1) this%origin = trim(this%cfg%run%checkpoint_file)
    call log_info('checkpoint: '//trim(this%cfg%run%checkpoint_file)//' at step '//itoa(k)// &
                  ', t = '//rtoa(t)//' s')
  end procedure write_checkpoint

  !> Restore the state of the checkpoint this run continues from (read_state) and the run's
  !> counters from its header. Collective.
  module procedure load_checkpoint
    call read_state(this, trim(this%cfg%run%restart), this%restart, stat, msg)
    if (stat /= 0) then
      msg = 'restart: '//msg
      return
    end if
    this%e0 = this%restart%e0
    this%kick = this%restart%kick
    this%kick_step = this%restart%step
    this%e_scale = this%restart%e_scale
    this%last_balance = this%restart%last_balance
    this%warned = this%restart%warned /= 0
    this%last_sample = this%restart%last_sample
    this%last_frame_time = this%restart%last_frame_time
    ! the integrator redoes what it needs of the loaded state (its resume, called next)
  end procedure load_checkpoint

  !> Documented at its interface in iem_simulation.f90: the run's checkpointed fields
  !> registered, borrowed where the run's array spans the registry's entities (else copied
  !> in), the records of the owned nodes and of every local cell read over them (the halo
  !> columns keep their values), and the copied ones copied back.
  module procedure read_state
    type(field_registry_t), target :: reg
    real(wp) :: energy(energy_words)
    integer :: worst
    call state_to_registry(this, reg, .true., stat, borrow=.true.)
    call MPI_Allreduce(stat, worst, 1, MPI_INTEGER, MPI_MAX, this%comm)
    if (worst /= 0) then
      stat = 1
      msg = 'out of memory for the registry of the fields'
      call reg%free()
      return
    end if
    call checkpoint_read(path, this%comm, h, energy, reg, this%lat%node_runs%table(), &
                         this%lat%cell_runs%table(), stat, msg)
    if (stat /= 0) then
      call reg%free()
      return
    end if
    call state_from_registry(this, reg)
    call reg%free()
    call this%model%w_ext_acc%unpack(int(energy(1:exact_sum_packed_size), i8))
    call this%model%w_damp_acc%unpack(int(energy(exact_sum_packed_size + 1:), i8))
  end procedure read_state

  !> Documented at its interface in iem_simulation.f90.
  module procedure checkpoint_looks
    looks = mod(k, int(this%cfg%run%check_interval, i8)) == 0
    ! (no short-circuit in Fortran: test the interval before dividing by it)
    if (this%cfg%run%checkpoint_interval > 0.0_wp) then
      if (crossed(t_prev, t, this%cfg%run%checkpoint_interval)) looks = .true.
    end if
  end procedure checkpoint_looks

  !> Documented at its interface in iem_simulation.f90.
  module procedure checkpoint_if_due
    integer :: sig
    logical :: due, ok
    stat = 0
    msg = ''
    sig = 0
    ! (the same condition tells the driver which steps' states it may leave part way on)
    if (.not. checkpoint_looks(this, k, t_prev, t)) return
    if (mod(k, int(this%cfg%run%check_interval, i8)) == 0) then
      sig = signal_caught()
      call MPI_Allreduce(MPI_IN_PLACE, sig, 1, MPI_INTEGER, MPI_MAX, this%comm)
    end if
    due = sig /= 0
    ! (no short-circuit in Fortran: test the interval before dividing by it)
    if (this%cfg%run%checkpoint_interval > 0.0_wp) then
      if (crossed(t_prev, t, this%cfg%run%checkpoint_interval)) due = .true.
    end if
    if (.not. due) return
    ! the last step must stand on every rank before its state is written
    call this%integ%settle(this%st, ok)
    if (.not. ok) then
      call stop_rejected(this, k, t, stat, msg)
      return
    end if
    call write_checkpoint(this, k, t, sig, stat, msg)
    if (stat /= 0) return
    if (sig /= 0) then
      stat = 4
      msg = 'stopped by signal '//itoa(sig)//' at step '//itoa(k)//', t = '//rtoa(t)// &
            ' s, after writing the checkpoint '//trim(this%cfg%run%checkpoint_file)// &
            '; continue with restart = '''//trim(this%cfg%run%checkpoint_file)//''''
    end if
  end procedure checkpoint_if_due

  !> Reopen the output of the interrupted run to append to it, and record the continuation
  !> in it (/continuations).
  module procedure reopen_output
    character(len=64), allocatable :: names(:), sp_names(:)
    integer :: k
    allocate(names(size(this%cfg%probes)), sp_names(size(this%sp_probe)))
    do k = 1, size(names)
      names(k) = this%cfg%probes(k)%name
    end do
    do k = 1, size(sp_names)
      sp_names(k) = this%cfg%probes(this%sp_probe(k))%name
    end do
    call this%out%reopen(trim(this%cfg%run%output_file), this%comm, this%body%n_nodes, &
      this%body%n_cells, this%lat%owned_gids(), counted_cell_gids(this), names, &
      sp_names, this%restart%n_samples, this%restart%n_frames, stat, msg)
    if (stat /= 0) return
    this%output_open = .true.
    call this%out%record_continuation(trim(this%cfg%run%restart), this%restart%t, &
                                      this%restart%step, stat, msg)
  end procedure reopen_output

  !> A 64-bit hash (the checkpoint's word hash, chained) of what defines the model (grid,
  !> material, damping, conditions, loads, initial state, integrator, step): a checkpoint
  !> continues only the same model.
  integer(i8) function model_hash(this) result(h)
    type(simulation_t), intent(in) :: this
    character(len=:), allocatable :: sig
    character(len=64) :: b
    integer :: k
    associate(c => this%cfg)
      sig = trim(c%geometry%plane)//trim(c%geometry%cell)//trim(c%damping%kind)// &
            trim(c%run%integrator)
      write(b, '(2i12)') this%grid%nx, this%grid%ny
      sig = sig//b
      call add([c%geometry%length, c%geometry%height, c%geometry%thickness])
      do k = 1, size(c%materials)
        associate(m => c%materials(k))
          call add([m%young, m%poisson, m%density, m%tensile_strength, &
                    m%compressive_strength, m%shear_strength])
          write(b, '(l1, i6)') m%nonlinear, m%history_depth
          sig = sig//trim(m%name)//b
        end associate
      end do
      call add([this%model%alpha, this%model%beta, this%model%omega_cap, c%initial%velocity, &
                c%initial%angular_velocity, c%initial%center, this%dt])
      do k = 1, size(c%bcs)
        sig = sig//trim(c%bcs(k)%set%where)//trim(c%bcs(k)%kind)//trim(c%bcs(k)%tf%kind)
        call add([c%bcs(k)%set%box, c%bcs(k)%set%point, c%bcs(k)%velocity, &
                  merge(1.0_wp, 0.0_wp, c%bcs(k)%dof), c%bcs(k)%tf%t_start, c%bcs(k)%tf%t_ramp, &
                  min(c%bcs(k)%t_release, 1.0e300_wp)])
      end do
      do k = 1, size(c%loads)
        sig = sig//trim(c%loads(k)%set%where)//trim(c%loads(k)%kind)//trim(c%loads(k)%tf%kind)
        call add([c%loads(k)%set%box, c%loads(k)%set%point, c%loads(k)%value, &
                  c%loads(k)%tf%t_start, c%loads(k)%tf%t_ramp])
      end do
    end associate
    h = text_hash(sig)
  contains
    subroutine add(v)
      real(wp), intent(in) :: v(:)
      integer :: j
      do j = 1, size(v)
        write(b, '(es25.17e3)') v(j)
        sig = sig//trim(b)
      end do
    end subroutine add
  end function model_hash
end submodule iem_restart
